/* What the cell program offers the bus glue: the cell state, its lock, its identity. */
#ifndef CELL_APP_H
#define CELL_APP_H

#include <stdint.h>
#include "metacell.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * The control tick (TC3 interrupt) owns the cell state. Code outside it (the I2C
 * callbacks, loop()) must change it only between cell_app_lock() and
 * cell_app_unlock(), which hold off the tick (keep that short: a few calls of the
 * mc_cell_* setters; not nestable; never call from the tick itself). Reading a
 * single aligned 32-bit field (theta, torque, faults) needs no lock.
 */
mc_cell_t *cell_app_cell(void);
void cell_app_lock(void);
void cell_app_unlock(void);
/* Raw decoder positions now (counts), e.g. for mc_cell_zero(). */
void cell_app_positions(int32_t *pos_a, int32_t *pos_b);
/* Re-zero both angles at their current positions (takes the lock itself). */
void cell_app_zero(void);
/* Identity baked in at build time: cell 1..64 (16 on the rig as built) and its I2C address, or 0 / 0. */
uint8_t cell_app_index(void);
uint8_t cell_app_addr(void);
/* Control ticks run since start-up (wraps mod 2^32). */
uint32_t cell_app_ticks(void);
/* MC_RCAUSE_* bits read at boot, and the watchdog timeout in force (ms, 0 = off). */
uint8_t cell_app_reset_cause(void);
uint16_t cell_app_wdt_ms(void);
/* Exception number and stacked PC of the fault that caused the last reset (0 / 0: none). */
uint8_t cell_app_fault_exc(void);
uint32_t cell_app_fault_pc(void);

#ifdef __cplusplus
}
#endif

#endif /* CELL_APP_H */
