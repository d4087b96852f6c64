/* PM: the bus clock masks (an access to a peripheral whose APB clock is off is an error), CPU clock select, reset cause. */
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

/* a peripheral's bus clock enable, from the PM APBxMASK field of the same name: the byte of PM's registers that
 * holds it (-1: not gated) and its bit there */
static int apb_byte[SAM_MAX_PERIPH];
static uint8_t apb_bit[SAM_MAX_PERIPH];
static int apb_pm, apb_ready;

static void apb_table(void)
{
    if (apb_ready)
        return;
    int pm = apb_pm = sam_periph_index("PM");
    const char *regs[3] = {"APBAMASK", "APBBMASK", "APBCMASK"};
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        apb_byte[pi] = -1;
        const char *name = sam_periphs[pi].name;
        if (!strcmp(name, "PORT_IOBUS"))
            name = "PORT";
        for (int k = 0; k < 3; k++) {
            int ri = sam_reg_index(pm, regs[k]);
            const sam_field_t *f = ri >= 0 ? sam_field(ri, name) : NULL;
            if (f) {   /* the field's bit in the register's little-endian bytes */
                apb_byte[pi] = (int)(sam_regs[ri].offset + f->pos / 8u);
                apb_bit[pi] = (uint8_t)(1u << f->pos % 8u);
            }
        }
    }
    apb_ready = 1;
}

int sam_apb_on(sam_mcu_t *m, int pi)
{
    apb_table();
    if (apb_byte[pi] < 0)
        return 1;   /* not gated by PM (system control space, the DSU's debug side) */
    return (m->regs[apb_pm][apb_byte[pi]] & apb_bit[pi]) != 0;
}

static int pm_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    uint32_t off = sam_regs[ri].offset;
    (void)pi;
    if (off == PM_RCAUSE_OFFSET) {
        *v = m->reset_cause;
        return SAM_DONE;
    }
    if (off == PM_INTFLAG_OFFSET) {
        *v = PM_INTFLAG_CKRDY;   /* clock changes take effect at once */
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int pm_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if (off == PM_INTFLAG_OFFSET)
        return SAM_DONE;
    if (off == PM_INTENSET_OFFSET && (v & mask)) {
        sam_fail(m, "PM interrupts are not modelled (INTENSET = 0x%x)", v);
        return SAM_DONE;
    }
    if (off == PM_SLEEP_OFFSET || off == PM_CTRL_OFFSET) {
        if ((v & mask) != 0 && off == PM_CTRL_OFFSET)
            sam_fail(m, "PM.CTRL = 0x%x: external clock failure detection is not modelled", v);
    }
    uint32_t old = sam_reg_get(m, ri);
    sam_reg_put(m, ri, (old & ~mask) | (v & mask));
    if (sam_reg_get(m, ri) != old)
        sam_activity(m);
    if (off == PM_CPUSEL_OFFSET)
        sam_set_cpu_clock(m);
    return SAM_DONE;
}

const sam_model_t sam_model_pm = {"Pm", NULL, NULL, pm_read, pm_write, NULL};
