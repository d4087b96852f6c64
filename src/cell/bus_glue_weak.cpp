/* Weak no-op defaults of the bus hooks, so the cell program links without the I2C glue. */
#include "bus_glue.h"

extern "C" __attribute__((weak)) void bus_setup(uint8_t addr) { (void)addr; }
extern "C" __attribute__((weak)) void bus_service(void) {}
