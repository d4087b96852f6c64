/* SAMD21 system layer shared by cell and primary: reset cause at boot, watchdog, fault handlers. */
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

/*
 * Fault handlers. HardFault, SVCall, PendSV and every interrupt vector the program does not
 * handle (the core points them at Dummy_Handler, an endless loop that left the PWM at its last
 * duty and nSLEEP high until the watchdog fired) enter sys_fault(): it calls sys_safe_outputs()
 * first (cell: both drivers asleep), writes a record of the exception and the interrupted PC
 * to mc_fault_record, and requests a system reset. The record sits at a fixed RAM address
 * (platformio.ini: -Wl,--defsym=mc_fault_record=...), above what the UF2 bootloader uses and
 * below the stack the next boot needs before setup() reads it; RCAUSE says SYST for such a
 * reset, and sys_reset_cause() adds MC_RCAUSE_FAULT when it finds the record intact.
 */
typedef struct {
    uint32_t magic;   /* SYS_FAULT_MAGIC while the record is valid */
    uint32_t exc;     /* exception number (IPSR): 3 HardFault, 11 SVCall, 14 PendSV, 16+n IRQ n */
    uint32_t pc;      /* stacked PC: where the fault happened */
    uint32_t check;   /* ~(magic ^ exc ^ pc) */
} sys_fault_record_t;
#define SYS_FAULT_MAGIC 0x4D434654u   /* "MCFT" */

#ifdef __cplusplus
extern "C" {
#endif
extern volatile sys_fault_record_t mc_fault_record;
/* Provided by each program: put every output that moves something in its safe state. Runs
 * inside the fault handler: register writes only, no waits. */
void sys_safe_outputs(void);
/* Safe outputs, record, reset. frame = the exception's stacked registers (r0-r3, r12, lr, pc,
 * xpsr), ipsr = the exception number. */
void sys_fault(const uint32_t *frame, uint32_t ipsr) __attribute__((noreturn));
#ifdef __cplusplus
}
#endif

/* Bytes of USB input one pass of loop() handles at most (one full-speed packet): a host that
 * streams without pause must not starve the bus service and the watchdog feed. What is left
 * waits in the core's buffer, and USB flow control holds the host back. */
#define SYS_USB_RX_PER_PASS 64u

/* PM->RCAUSE as read now (MC_RCAUSE_* bits: the cause of the last reset), with MC_RCAUSE_FAULT
 * added when the reset came from sys_fault(). Call once, first thing in setup(): it consumes
 * the fault record (sys_fault_exc/_pc keep it). */
uint8_t sys_reset_cause(void);
/* Exception number and PC of the fault that caused the last reset (0 when none). */
uint8_t sys_fault_exc(void);
uint32_t sys_fault_pc(void);
/* Start the watchdog (SYS_WDT_MS). Call once, late in setup(). */
void sys_wdt_start(void);
/* Restart the watchdog period; never waits (skips while the previous clear synchronises,
 * ~3 WDT clocks = 3 ms, far below the period). Returns 1 when it fed, 0 when it skipped.
 * Call from loop() when the work it guards has progressed (cell: the control tick). */
int sys_wdt_feed(void);

#endif /* SAMD21_SYS_H */
