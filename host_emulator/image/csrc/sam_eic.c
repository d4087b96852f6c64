/* EIC: external interrupt lines from the pins their PMUX A selects, sense modes, flags and the interrupt. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

static int eic_pi = -1;
static int8_t eic_line_of_pin[64];   /* EXTINTn on PMUX function A, from the generated pin table; -1 */
static int8_t eic_nmi_pin = -1;

static void eic_tables(void)
{
    if (eic_pi >= 0)
        return;
    eic_pi = sam_periph_index("EIC");
    memset(eic_line_of_pin, -1, sizeof eic_line_of_pin);
    for (unsigned k = 0; k < sam_npinmux; k++) {
        const sam_pinmux_t *f = &sam_pinmux[k];
        if (f->func == 0 && !strcmp(f->periph, "EIC")) {
            if (!strncmp(f->signal, "EXTINT", 6))
                eic_line_of_pin[f->pin] = (int8_t)atoi(f->signal + 6);
            else if (!strcmp(f->signal, "NMI"))
                eic_nmi_pin = (int8_t)f->pin;
        }
    }
}

typedef struct {
    int8_t line_pin[16];   /* pin feeding each line through PMUX A, -1 */
    uint8_t in[16];        /* line input levels */
} eic_t;

static uint32_t eic_reg(sam_mcu_t *m, uint32_t off) { return sam_rd32(m->regs[eic_pi] + off); }

static void eic_irq(sam_mcu_t *m)
{
    uint32_t flags = eic_reg(m, EIC_INTFLAG_OFFSET) & eic_reg(m, EIC_INTENSET_OFFSET);
    sam_irq_level(m, sam_periphs[eic_pi].irq, flags != 0);
}

static int eic_running(sam_mcu_t *m)
{
    return (m->regs[eic_pi][EIC_CTRL_OFFSET] & EIC_CTRL_ENABLE) && sam_gclk_hz(m, EIC_GCLK_ID) != 0;
}

static unsigned eic_sense(sam_mcu_t *m, int line)
{
    return (eic_reg(m, EIC_CONFIG_OFFSET + 4u * (uint32_t)(line / 8)) >> (4 * (line % 8))) & 7u;
}

static void eic_flag(sam_mcu_t *m, int line)
{
    uint8_t *f = m->regs[eic_pi] + EIC_INTFLAG_OFFSET;
    uint32_t v = sam_rd32(f) | 1u << line;
    f[0] = (uint8_t)v;
    f[1] = (uint8_t)(v >> 8);
    f[2] = (uint8_t)(v >> 16);
    f[3] = (uint8_t)(v >> 24);
    sam_activity(m);
}

static void eic_line_input(sam_mcu_t *m, int line, int level)
{
    eic_t *e = m->pst[eic_pi];
    if (!e || e->in[line] == level)
        return;
    e->in[line] = (uint8_t)level;
    if (!eic_running(m))
        return;
    unsigned s = eic_sense(m, line);
    if ((s == EIC_CONFIG_SENSE0_RISE_Val && level) || (s == EIC_CONFIG_SENSE0_FALL_Val && !level) ||
        s == EIC_CONFIG_SENSE0_BOTH_Val || (s == EIC_CONFIG_SENSE0_HIGH_Val && level) ||
        (s == EIC_CONFIG_SENSE0_LOW_Val && !level)) {
        eic_flag(m, line);
        eic_irq(m);
    }
}

/* level-sensed lines raise their flag again while the level holds */
static void eic_levels(sam_mcu_t *m)
{
    eic_t *e = m->pst[eic_pi];
    if (!eic_running(m))
        return;
    for (int l = 0; l < 16; l++) {
        unsigned s = eic_sense(m, l);
        if ((s == EIC_CONFIG_SENSE0_HIGH_Val && e->in[l]) || (s == EIC_CONFIG_SENSE0_LOW_Val && !e->in[l]))
            if (!(eic_reg(m, EIC_INTFLAG_OFFSET) >> l & 1u))
                eic_flag(m, l);
    }
    eic_irq(m);
}

void sam_eic_lines_update(sam_mcu_t *m)
{
    eic_tables();
    eic_t *e = m->pst[eic_pi];
    if (!e)
        return;
    int8_t lp[16];
    memset(lp, -1, sizeof lp);
    for (int p = 0; p < 64; p++) {
        int l = eic_line_of_pin[p];
        if (l < 0 || sam_pin_function(m, p) != 0)
            continue;
        if (lp[l] >= 0) {
            sam_fail(m, "pins %d and %d both muxed to EIC line %d", lp[l], p, l);
            return;
        }
        lp[l] = (int8_t)p;
    }
    memcpy(e->line_pin, lp, sizeof lp);
    for (int l = 0; l < 16; l++)
        eic_line_input(m, l, lp[l] >= 0 ? sam_pin_level(m, lp[l]) : 0);
}

/* a pin's level changed: the line it feeds through PMUX A sees it */
void sam_eic_pin_input(sam_mcu_t *m, int pin, int level)
{
    eic_tables();
    int line = eic_line_of_pin[pin];
    if (line >= 0 && sam_pin_function(m, pin) == 0)
        eic_line_input(m, line, level);
}

static void eic_reset(sam_mcu_t *m, int pi)
{
    eic_tables();
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(eic_t));
    memset(m->pst[pi], 0, sizeof(eic_t));
    memset(((eic_t *)m->pst[pi])->line_pin, -1, 16);
}

static int eic_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    if (sam_regs[ri].offset == EIC_STATUS_OFFSET) {
        *v = 0;   /* synchronisation of the EIC completes within a few GCLK_EIC cycles */
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int eic_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint32_t off = sam_regs[ri].offset;
    v &= mask;
    if (off == EIC_CTRL_OFFSET) {
        if (v & EIC_CTRL_SWRST) {
            uint8_t *regs = m->regs[pi];
            memset(regs, 0, sam_periphs[pi].size);
            eic_reset(m, pi);
            sam_eic_lines_update(m);
            eic_irq(m);
            sam_activity(m);
            return SAM_DONE;
        }
        sam_generic_write(m, ri, v, mask);
        sam_eic_lines_update(m);
        eic_levels(m);
        return SAM_DONE;
    }
    if ((off == EIC_NMICTRL_OFFSET || off == EIC_EVCTRL_OFFSET) && v) {
        sam_fail(m, "%s = 0x%x: the EIC's NMI and event outputs are not modelled", sam_regs[ri].name, v);
        return SAM_DONE;
    }
    sam_generic_write(m, ri, v, mask);
    if (off == EIC_INTFLAG_OFFSET || off == EIC_CONFIG_OFFSET || off == EIC_CONFIG_OFFSET + 4)
        eic_levels(m);
    eic_irq(m);
    return SAM_DONE;
}

const sam_model_t sam_model_eic = {"Eic", eic_reset, NULL, eic_read, eic_write, NULL};
