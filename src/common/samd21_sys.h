/* SAMD21 system layer shared by cell and primary: reset cause at boot, watchdog start and feed. */
#ifndef SAMD21_SYS_H
#define SAMD21_SYS_H

#include <stdint.h>

/*
 * Watchdog: WDT clocked by GCLK2 = OSCULP32K / 32 = 1024 Hz, normal mode, period
 * 1024 clocks = SYS_WDT_MS (1.0 s). The longest legitimate pause of either main loop
 * is far below it: a USB write that times out (70 ms in the core), an I2C transaction
 * (bounded in primary_hw.cpp, < 3 ms) and a bus recovery (< 0.2 ms). A loop that stops
 * for 1 s resets the chip; the next boot reads RCAUSE.WDT and reports it (cell: BOOT
 * block; primary: PRIMARY_HEALTH frame).
 */
#define SYS_WDT_MS 1000u

/* PM->RCAUSE as read now (MC_RCAUSE_* bits: the cause of the last reset). */
uint8_t sys_reset_cause(void);
/* Start the watchdog (SYS_WDT_MS). Call once, late in setup(). */
void sys_wdt_start(void);
/* Restart the watchdog period; never waits (skips while the previous clear synchronises,
 * ~3 WDT clocks = 3 ms, far below the period). Returns 1 when it fed, 0 when it skipped.
 * Call from loop() when the work it guards has progressed (cell: the control tick). */
int sys_wdt_feed(void);

#endif /* SAMD21_SYS_H */
