/* SAMD21 system layer: PM reset cause, WDT on GCLK2 (OSCULP32K / 32) with a 1 s period, non-blocking feed. */
#include <Arduino.h>
#include "samd21_sys.h"
extern "C" {
#include "bus/mc_proto.h"
}

/* The wire's reset-cause bits are the RCAUSE register's (protocol/definition.py RESET_CAUSE). */
static_assert(MC_RCAUSE_POR == PM_RCAUSE_POR && MC_RCAUSE_BOD12 == PM_RCAUSE_BOD12 &&
                  MC_RCAUSE_BOD33 == PM_RCAUSE_BOD33 && MC_RCAUSE_EXT == PM_RCAUSE_EXT &&
                  MC_RCAUSE_WDT == PM_RCAUSE_WDT && MC_RCAUSE_SYST == PM_RCAUSE_SYST,
              "RESET_CAUSE bits differ from PM RCAUSE");

uint8_t sys_reset_cause(void) { return (uint8_t)PM->RCAUSE.reg; }

void sys_wdt_start(void)
{
    /* GCLK2 = OSCULP32K / 2^(DIV + 1) = 32768 / 32 = 1024 Hz (DIVSEL: power-of-two divider). */
    GCLK->GENDIV.reg = GCLK_GENDIV_ID(2) | GCLK_GENDIV_DIV(4);
    while (GCLK->STATUS.bit.SYNCBUSY) {
    }
    GCLK->GENCTRL.reg = GCLK_GENCTRL_ID(2) | GCLK_GENCTRL_SRC_OSCULP32K | GCLK_GENCTRL_GENEN |
                        GCLK_GENCTRL_DIVSEL;
    while (GCLK->STATUS.bit.SYNCBUSY) {
    }
    GCLK->CLKCTRL.reg = GCLK_CLKCTRL_ID_WDT | GCLK_CLKCTRL_CLKEN | GCLK_CLKCTRL_GEN_GCLK2;
    while (GCLK->STATUS.bit.SYNCBUSY) {
    }
    WDT->CTRL.reg = 0;   /* configure while disabled */
    while (WDT->STATUS.bit.SYNCBUSY) {
    }
    WDT->CONFIG.reg = WDT_CONFIG_PER_1K;   /* 1024 clocks at 1024 Hz = SYS_WDT_MS */
    while (WDT->STATUS.bit.SYNCBUSY) {
    }
    WDT->CTRL.reg = WDT_CTRL_ENABLE;
    while (WDT->STATUS.bit.SYNCBUSY) {
    }
}

int sys_wdt_feed(void)
{
    /* writing CLEAR while a clear is still synchronising would stall the bus: skip instead */
    if (WDT->STATUS.bit.SYNCBUSY)
        return 0;
    WDT->CLEAR.reg = WDT_CLEAR_CLEAR_KEY;
    return 1;
}
