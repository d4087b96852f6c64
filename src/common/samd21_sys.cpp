/* SAMD21 system layer: PM reset cause, WDT on GCLK2 (OSCULP32K / 32) with a 1 s period, non-blocking feed, fault handlers. */
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
static_assert((MC_RCAUSE_FAULT & (PM_RCAUSE_POR | PM_RCAUSE_BOD12 | PM_RCAUSE_BOD33 | PM_RCAUSE_EXT |
                                  PM_RCAUSE_WDT | PM_RCAUSE_SYST)) == 0,
              "RESET_CAUSE FAULT must be a bit RCAUSE never sets");

static uint8_t s_fault_exc;
static uint32_t s_fault_pc;

static uint32_t fault_check(uint32_t exc, uint32_t pc) { return ~(SYS_FAULT_MAGIC ^ exc ^ pc); }

uint8_t sys_reset_cause(void)
{
    uint8_t cause = (uint8_t)PM->RCAUSE.reg;
    volatile sys_fault_record_t *r = &mc_fault_record;
    s_fault_exc = 0;
    s_fault_pc = 0;
    /* only a software reset can come from sys_fault(); after a power-on the RAM is noise */
    if ((cause & PM_RCAUSE_SYST) && r->magic == SYS_FAULT_MAGIC &&
        r->check == fault_check(r->exc, r->pc)) {
        cause |= MC_RCAUSE_FAULT;
        s_fault_exc = (uint8_t)r->exc;
        s_fault_pc = r->pc;
    }
    r->magic = 0;   /* consumed: a later plain reset must not report it again */
    return cause;
}

uint8_t sys_fault_exc(void) { return s_fault_exc; }
uint32_t sys_fault_pc(void) { return s_fault_pc; }

extern "C" void sys_fault(const uint32_t *frame, uint32_t ipsr)
{
    sys_safe_outputs();
    /* the frame was just written by the exception entry, so it is readable RAM */
    uint32_t exc = ipsr & 0x3fu, pc = frame[6];
    mc_fault_record.exc = exc;
    mc_fault_record.pc = pc;
    mc_fault_record.check = fault_check(exc, pc);
    mc_fault_record.magic = SYS_FAULT_MAGIC;
    NVIC_SystemReset();   /* DSB, SYSRESETREQ; RCAUSE.SYST at the next boot */
}

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
