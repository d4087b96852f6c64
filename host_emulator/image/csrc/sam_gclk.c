/* GCLK: the generic clock generators (source, divider) and the peripheral channels, with cached frequencies. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

#define NGEN 9
#define NCHAN 0x25

static uint32_t field_get(uint32_t v, uint32_t pos, uint32_t width) { return (v >> pos) & ((1u << width) - 1u); }

typedef struct {
    uint32_t genctrl[NGEN], gendiv[NGEN];
    uint16_t clkctrl[NCHAN];
    int sel_clk, sel_gen, sel_div;
    uint64_t chan_hz[NCHAN];   /* cached frequencies, valid while chan_epoch == the board's clk_epoch */
    uint32_t chan_epoch[NCHAN];
} gclk_t;

static gclk_t *gclk_state(sam_mcu_t *m) { return m->pst[sam_idx.gclk]; }

static void gclk_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(gclk_t));
    gclk_t *g = m->pst[pi];
    memset(g, 0, sizeof *g);
    for (int i = 0; i < NGEN; i++) {
        g->genctrl[i] = (uint32_t)i;
        g->gendiv[i] = (uint32_t)i;
    }
    g->genctrl[0] |= GCLK_GENCTRL_SRC_OSC8M | GCLK_GENCTRL_GENEN;      /* GCLK0: OSC8M (its /8 prescaler: 1 MHz) */
    g->genctrl[2] |= GCLK_GENCTRL_SRC_OSCULP32K | GCLK_GENCTRL_GENEN;  /* GCLK2: the watchdog's reset clock */
    for (int i = 0; i < NCHAN; i++)
        g->clkctrl[i] = (uint16_t)i;
    g->clkctrl[WDT_GCLK_ID] |= GCLK_CLKCTRL_GEN_GCLK2 | GCLK_CLKCTRL_CLKEN;
}

static uint64_t source_hz(sam_mcu_t *m, gclk_t *g, uint32_t src, int depth)
{
    switch (src) {
    case GCLK_GENCTRL_SRC_GCLKGEN1_Val: {
        if (depth > 2)
            return 0;
        uint32_t gc = g->genctrl[1];
        if (!(gc & GCLK_GENCTRL_GENEN))
            return 0;
        uint64_t hz = source_hz(m, g, field_get(gc, GCLK_GENCTRL_SRC_Pos, 5), depth + 1);
        uint32_t div = field_get(g->gendiv[1], GCLK_GENDIV_DIV_Pos, 16);
        if (gc & GCLK_GENCTRL_DIVSEL)
            return hz >> (div + 1);
        return div > 1 ? hz / div : hz;
    }
    default: return sam_sysctrl_osc_hz(m, src);   /* GCLKIN: not fitted on the XIAO */
    }
}

uint64_t sam_gen_hz(sam_mcu_t *m, int gen)
{
    gclk_t *g = gclk_state(m);
    if (!g || gen < 0 || gen >= NGEN)
        return gen == 0 ? 1000000u : 0;
    uint32_t gc = g->genctrl[gen];
    if (!(gc & GCLK_GENCTRL_GENEN))
        return 0;
    uint64_t hz = source_hz(m, g, field_get(gc, GCLK_GENCTRL_SRC_Pos, 5), 0);
    uint32_t div = field_get(g->gendiv[gen], GCLK_GENDIV_DIV_Pos, gen == 1 ? 16 : gen == 2 ? 5 : 8);
    if (gc & GCLK_GENCTRL_DIVSEL)
        return hz >> (div + 1);
    return div > 1 ? hz / div : hz;
}

uint64_t sam_gclk_hz(sam_mcu_t *m, int id)
{
    gclk_t *g = gclk_state(m);
    if (!g || id < 0 || id >= NCHAN)
        return 0;
    if (g->chan_epoch[id] == m->clk_epoch + 1u)
        return g->chan_hz[id];
    uint16_t c = g->clkctrl[id];
    uint64_t hz = c & GCLK_CLKCTRL_CLKEN ? sam_gen_hz(m, (int)field_get(c, GCLK_CLKCTRL_GEN_Pos, 4)) : 0;
    /* a source still starting up (XOSC32K) changes with time, not with a write: not cached until it runs */
    if (hz || !(c & GCLK_CLKCTRL_CLKEN)) {
        g->chan_hz[id] = hz;
        g->chan_epoch[id] = m->clk_epoch + 1u;
    }
    return hz;
}

static int gclk_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    gclk_t *g = m->pst[pi];
    switch (sam_regs[ri].offset) {
    case GCLK_CTRL_OFFSET: *v = 0; return SAM_DONE;                 /* SWRST completes at once */
    case GCLK_STATUS_OFFSET: *v = 0; return SAM_DONE;               /* synchronisation is immediate */
    case GCLK_CLKCTRL_OFFSET: *v = g->clkctrl[g->sel_clk]; return SAM_DONE;
    case GCLK_GENCTRL_OFFSET: *v = g->genctrl[g->sel_gen]; return SAM_DONE;
    case GCLK_GENDIV_OFFSET: *v = g->gendiv[g->sel_div]; return SAM_DONE;
    default: return SAM_UNCOVERED;
    }
}

static int gclk_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    gclk_t *g = m->pst[pi];
    switch (sam_regs[ri].offset) {
    case GCLK_CTRL_OFFSET:
        if (v & mask & GCLK_CTRL_SWRST) {
            gclk_reset(m, pi);
            sam_set_cpu_clock(m);
        }
        break;
    case GCLK_CLKCTRL_OFFSET: {
        int id = (int)(v & 0x3Fu);
        if (id >= NCHAN) {
            sam_fail(m, "GCLK.CLKCTRL.ID = 0x%x: no such channel", id);
            return SAM_DONE;
        }
        g->sel_clk = id;
        if (mask & 0xFF00u) {   /* a byte write of ID only selects the channel to read */
            if (g->clkctrl[id] & GCLK_CLKCTRL_WRTLOCK)
                break;
            g->clkctrl[id] = (uint16_t)v;
        }
        break;
    }
    case GCLK_GENCTRL_OFFSET: {
        int id = (int)(v & 0xFu);
        if (id >= NGEN) {
            sam_fail(m, "GCLK.GENCTRL.ID = %d: no such generator", id);
            return SAM_DONE;
        }
        g->sel_gen = id;
        if (mask & ~0xFFu) {
            g->genctrl[id] = v;
            if (v & GCLK_GENCTRL_OE)
                sam_fail(m, "GCLK generator %d output to a pin (GENCTRL.OE) is not modelled", id);
        }
        break;
    }
    case GCLK_GENDIV_OFFSET: {
        int id = (int)(v & 0xFu);
        if (id >= NGEN) {
            sam_fail(m, "GCLK.GENDIV.ID = %d: no such generator", id);
            return SAM_DONE;
        }
        g->sel_div = id;
        if (mask & ~0xFFu)
            g->gendiv[id] = v;
        break;
    }
    default: return SAM_UNCOVERED;
    }
    sam_activity(m);
    sam_set_cpu_clock(m);
    return SAM_DONE;
}

const sam_model_t sam_model_gclk = {"Gclk", gclk_reset, NULL, gclk_read, gclk_write, NULL};

/* tu per count of a counter clocked at hz / presc (0: no clock, or not a whole number of tu: sam_fail) */
uint64_t sam_tu_per_tick(sam_mcu_t *m, uint64_t hz, uint32_t presc, const char *what)
{
    if (!hz)
        return 0;
    if ((SAM_TU_HZ * presc) % hz) {
        sam_fail(m, "%s clocked at %llu Hz / %u: not a whole number of time units per count", what,
                 (unsigned long long)hz, presc);
        return 0;
    }
    return SAM_TU_HZ * presc / hz;
}
