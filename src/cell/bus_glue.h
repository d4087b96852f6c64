/* Hooks for the I2C secondary (docs/datapath.md): called by the cell program, weak no-ops by default. */
#ifndef CELL_BUS_GLUE_H
#define CELL_BUS_GLUE_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/*
 * The bus helper implements these two in its own file under src/cell/ (strong
 * definitions replace the weak ones in bus_glue_weak.cpp at link time):
 *
 *   bus_setup(addr)  once, from setup(), after the control tick is running; only
 *                    for an addressed image (addr = MC_CELL_ADDR, 0x08..0x77).
 *                    Pins: SDA = D4 (PA08), SCL = D5 (PA09), SERCOM2 (Wire).
 *   bus_service()    from every pass of loop(); must not block.
 *
 * Use cell_app.h to reach the cell state, under cell_app_lock() for writes.
 */
void bus_setup(uint8_t addr);
void bus_service(void);

#ifdef __cplusplus
}
#endif

#endif /* CELL_BUS_GLUE_H */
