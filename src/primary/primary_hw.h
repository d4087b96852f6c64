/* Primary hardware layer: guarded Wire transactions on SERCOM2, microsecond clock, USB transmit room. */
#ifndef PRIMARY_HW_H
#define PRIMARY_HW_H

#include <stdint.h>
extern "C" {
#include "bus/mc_primary.h"
}

/* Wire primary at hz with the SERCOM SCL-low and inactive-bus timeouts enabled. */
void primary_hw_begin(uint32_t hz);
/* Run one transaction; returns an MC_I2C_* status, read bytes in rx[0..*len). */
int primary_hw_txn(const mc_txn_t *t, uint8_t *rx, uint32_t *len);
uint32_t primary_hw_micros(void);
/* Bytes the USB CDC transmit buffer takes now without blocking. */
int primary_hw_usb_room(void);

#endif /* PRIMARY_HW_H */
