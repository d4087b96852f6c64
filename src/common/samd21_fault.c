/* Fault vectors of both images: one naked entry (stacked frame + IPSR -> sys_fault) and the strong handler aliases. */

/*
 * C, not C++: the handler aliases must carry the same attributes as their target, and a C++
 * translation unit marks them nothrow. sys_fault() itself is in samd21_sys.cpp.
 */
void sys_fault_entry(void);

#if defined(__arm__) && defined(__thumb__)
/*
 * The one entry of every exception that must never happen: pass the stacked frame (MSP or
 * PSP, per EXC_RETURN bit 2) and IPSR to sys_fault(). Naked: no prologue may touch a stack
 * that may be the reason for the fault.
 */
__attribute__((naked)) void sys_fault_entry(void)
{
    __asm volatile(
        "movs r0, #4\n\t"
        "mov r1, lr\n\t"
        "tst r0, r1\n\t"
        "beq 1f\n\t"
        "mrs r0, psp\n\t"
        "b 2f\n"
        "1:\n\t"
        "mrs r0, msp\n"
        "2:\n\t"
        "mrs r1, ipsr\n\t"
        "bl sys_fault\n\t");
}

/*
 * Strong definitions replace the core's weak aliases of Dummy_Handler (cortex_handlers.c).
 * Not listed: Reset, SysTick and USB (the core's), SERCOM2 (Wire), SERCOM4 (the variant's
 * Serial1), and on the cell EIC and NMI (WInterrupts.c) and TC3 (the control tick). A vector
 * listed here that another object also defines fails the link, never silently.
 * `python -m metacell_tools.fwcheck vectors --elf` checks the linked vector table.
 */
#define SYS_FAULT_VECTOR(name) void name(void) __attribute__((alias("sys_fault_entry")));
SYS_FAULT_VECTOR(HardFault_Handler)
SYS_FAULT_VECTOR(SVC_Handler)
SYS_FAULT_VECTOR(PendSV_Handler)
SYS_FAULT_VECTOR(PM_Handler)
SYS_FAULT_VECTOR(SYSCTRL_Handler)
SYS_FAULT_VECTOR(WDT_Handler)
SYS_FAULT_VECTOR(RTC_Handler)
SYS_FAULT_VECTOR(NVMCTRL_Handler)
SYS_FAULT_VECTOR(DMAC_Handler)
SYS_FAULT_VECTOR(EVSYS_Handler)
SYS_FAULT_VECTOR(SERCOM0_Handler)
SYS_FAULT_VECTOR(SERCOM1_Handler)
SYS_FAULT_VECTOR(SERCOM3_Handler)
SYS_FAULT_VECTOR(SERCOM5_Handler)
SYS_FAULT_VECTOR(TCC0_Handler)
SYS_FAULT_VECTOR(TCC1_Handler)
SYS_FAULT_VECTOR(TCC2_Handler)
SYS_FAULT_VECTOR(TC4_Handler)
SYS_FAULT_VECTOR(TC5_Handler)
SYS_FAULT_VECTOR(TC6_Handler)
SYS_FAULT_VECTOR(TC7_Handler)
SYS_FAULT_VECTOR(ADC_Handler)
SYS_FAULT_VECTOR(AC_Handler)
SYS_FAULT_VECTOR(DAC_Handler)
SYS_FAULT_VECTOR(PTC_Handler)
SYS_FAULT_VECTOR(I2S_Handler)
#ifdef MC_ROLE_PRIMARY
SYS_FAULT_VECTOR(NMI_Handler)
SYS_FAULT_VECTOR(EIC_Handler)
SYS_FAULT_VECTOR(TC3_Handler)
#endif
#endif
