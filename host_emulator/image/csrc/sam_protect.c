/* Enable protection (DS40001882 "Enable-Protected"): the fields a write cannot change while their peripheral is enabled. */
#include "sam.h"

/*
 * The datasheet marks a register or some of its fields "Enable-Protected": they can be written only while the
 * peripheral's ENABLE bit (as synchronised) reads 0; a write while it reads 1 leaves them as they are, and writes
 * the register's other fields. The registers and fields here (every one a model of this tier stores):
 *
 *   WDT.CONFIG (PER, WINDOW), WDT.EWCTRL (EWOFFSET)      18.8.2 CONFIG, 18.8.3 EWCTRL: the whole register
 *   TCn.CTRLA: PRESCSYNC, RUNSTDBY, PRESCALER, WAVEGEN, MODE   30.8.1 CTRLA (ENABLE and SWRST are not)
 *   SERCOMn.I2CM.CTRLA, I2CS.CTRLA: all but SWRST and ENABLE  28 "SERCOM I2C", the CTRLA of each mode
 *   SERCOMn.I2CM.BAUD                                     28 "SERCOM I2C", master BAUD: the whole register
 *   TCCn.CTRLA: RESOLUTION, PRESCALER, RUNSTDBY, PRESCSYNC, ALOCK, CPTENn   31.8.1 CTRLA (not ENABLE, SWRST)
 *   TCCn.FCTRLA, FCTRLB, WEXCTRL, DRVCTRL, EVCTRL         31.8, each marked Enable-Protected: the whole register
 *                                                         (WAVE is not, on the SAMD21)
 *
 * Such a write is almost always a defect (an image that enables the watchdog before configuring it gets the
 * fuse's period on a board): each is noted, once per register and board.
 */
uint32_t sam_enable_protected(sam_mcu_t *m, int ri, uint32_t v, uint32_t mask, uint32_t protect, int enabled)
{
    if (!enabled || !(mask & protect))
        return v;
    uint32_t old = sam_reg_get(m, ri);
    uint32_t kept = (v & ~protect) | (old & protect & mask);
    if ((v & protect & mask) != (old & protect & mask)) {
        unsigned bit = (unsigned)ri % 64u;
        if (!(m->ep_noted >> bit & 1u)) {
            m->ep_noted |= 1ull << bit;
            sam_note(m, "%s: write of 0x%x to %s while enabled: its enable-protected fields (0x%x) are kept, as on "
                     "silicon, at t = %.6f s", m->name, v, sam_regs[ri].name, protect, (double)m->t / (double)SAM_TU_HZ);
        }
        m->ep_writes++;
    }
    return kept;
}
