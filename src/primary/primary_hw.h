/* Primary hardware layer: bounded I2C transactions on SERCOM2, bus recovery count, microsecond clock. */
#ifndef PRIMARY_HW_H
#define PRIMARY_HW_H

#include <stdint.h>
extern "C" {
#include "bus/mc_primary.h"
}

/* I2C master at hz on SERCOM2; its SMBus timeouts stay off (primary_hw.cpp says why). */
void primary_hw_begin(uint32_t hz);
/* Run one transaction within t->timeout_us (every wait bounded); returns an MC_I2C_*
 * status, read bytes in rx[0..*len) (*len = 0 unless MC_I2C_OK). */
int primary_hw_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len);
/* Bus recoveries (9 clocks + STOP) since boot. */
uint32_t primary_hw_bus_resets(void);
uint32_t primary_hw_micros(void);

#endif /* PRIMARY_HW_H */
