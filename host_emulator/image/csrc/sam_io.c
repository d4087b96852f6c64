/* I/O peripherals: PORT (APB and IOBUS doors, input sampling), EIC (pin interrupts), TC (16-bit timer), TCC (PWM). */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

#define SYNC_GCLK_CYCLES 3u   /* write-synchronisation: a few cycles of the peripheral's generic clock */

static uint32_t rd32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }

static uint64_t tu_per_tick(sam_mcu_t *m, uint64_t hz, uint32_t presc, const char *what)
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

/* ================================================================ PORT */

typedef struct {
    int8_t ext[64];        /* level the board drives onto the pin, -1: none */
    uint32_t lvl[2];       /* pad levels */
    uint32_t sampled[2];   /* IN as the last APB read sampled it (on-demand pins) */
} port_t;

static int port_pi = -1, iobus_pi = -1, eic_pi = -1;
static int8_t eic_line_of_pin[64];   /* EXTINTn on PMUX function A, from the generated pin table; -1 */
static int8_t eic_nmi_pin = -1;

static void port_tables(void)
{
    if (port_pi >= 0)
        return;
    port_pi = sam_periph_index("PORT");
    iobus_pi = sam_periph_index("PORT_IOBUS");
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

static port_t *port_st(sam_mcu_t *m) { return m->pst[port_pi]; }
static uint8_t *grp(sam_mcu_t *m, int g) { return m->regs[port_pi] + 0x80 * g; }

static uint32_t port_dir(sam_mcu_t *m, int g) { return rd32(grp(m, g) + PORT_DIR_OFFSET); }
static uint32_t port_out(sam_mcu_t *m, int g) { return rd32(grp(m, g) + PORT_OUT_OFFSET); }
static uint32_t port_ctrl(sam_mcu_t *m, int g) { return rd32(grp(m, g) + PORT_CTRL_OFFSET); }
static uint8_t port_pincfg(sam_mcu_t *m, int pin) { return grp(m, pin >> 5)[PORT_PINCFG_OFFSET + (pin & 31)]; }

int sam_pin_function(sam_mcu_t *m, int pin)
{
    port_tables();
    if (!(port_pincfg(m, pin) & PORT_PINCFG_PMUXEN))
        return -1;
    uint8_t pm = grp(m, pin >> 5)[PORT_PMUX_OFFSET + ((pin & 31) >> 1)];
    return pin & 1 ? pm >> 4 : pm & 15;
}

int sam_pin_out(sam_mcu_t *m, int pin, int *driven)
{
    port_tables();
    int g = pin >> 5, b = pin & 31;
    int gpio_out = !(port_pincfg(m, pin) & PORT_PINCFG_PMUXEN) && (port_dir(m, g) >> b & 1u);
    *driven = gpio_out;
    if (gpio_out)
        return (int)(port_out(m, g) >> b & 1u);
    if (port_pincfg(m, pin) & PORT_PINCFG_PULLEN)
        return (int)(port_out(m, g) >> b & 1u);   /* pull direction */
    return -1;
}

static int pad_level(sam_mcu_t *m, port_t *s, int pin)
{
    int driven;
    int o = sam_pin_out(m, pin, &driven);
    if (driven)
        return o;
    if (s->ext[pin] >= 0)
        return s->ext[pin];
    return o > 0 ? 1 : 0;   /* pull-up, pull-down, or floating (read as 0) */
}

int sam_pin_level(sam_mcu_t *m, int pin)
{
    port_tables();
    return (int)(port_st(m)->lvl[pin >> 5] >> (pin & 31) & 1u);
}

static void eic_line_input(sam_mcu_t *m, int line, int level);
static void eic_lines_update(sam_mcu_t *m);

/* recompute a group's pad levels; tell the EIC about changes on its lines */
static void port_levels(sam_mcu_t *m, int g)
{
    port_t *s = port_st(m);
    uint32_t lv = 0;
    for (int b = 0; b < 32; b++)
        lv |= (uint32_t)pad_level(m, s, 32 * g + b) << b;
    uint32_t ch = lv ^ s->lvl[g];
    s->lvl[g] = lv;
    if (ch)
        eic_lines_update(m);
}

void sam_pin_drive(sam_mcu_t *m, int pin, int level)
{
    port_tables();
    port_t *s = port_st(m);
    if (!s)
        return;
    if (level == 2)   /* toggle (a glitch of an edge storm) */
        level = s->ext[pin] > 0 ? 0 : 1;
    if (s->ext[pin] == level)
        return;
    s->ext[pin] = (int8_t)level;
    int g = pin >> 5, b = pin & 31;
    int nl = pad_level(m, s, pin);
    if ((int)(s->lvl[g] >> b & 1u) != nl) {
        s->lvl[g] ^= 1u << b;
        int line = eic_line_of_pin[pin];
        if (line >= 0 && sam_pin_function(m, pin) == 0)
            eic_line_input(m, line, nl);
    }
}

static void port_reset(sam_mcu_t *m, int pi)
{
    port_tables();
    if (pi != port_pi)
        return;
    port_t *old = m->pst[pi];
    int8_t ext[64];
    if (old)
        memcpy(ext, old->ext, sizeof ext);   /* the board keeps driving its pins through a reset */
    else
        memset(ext, -1, sizeof ext);
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(port_t));
    port_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    memcpy(s->ext, ext, sizeof ext);
    for (int g = 0; g < 2; g++)
        for (int b = 0; b < 32; b++)
            s->lvl[g] |= (uint32_t)pad_level(m, s, 32 * g + b) << b;
}

static int port_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    port_t *s = port_st(m);
    uint32_t off = sam_regs[ri].offset, g = off / 0x80, r = off % 0x80;
    if (r != PORT_IN_OFFSET)
        return SAM_GENERIC;
    uint32_t inen = 0;
    for (int b = 0; b < 32; b++)
        if (grp(m, (int)g)[PORT_PINCFG_OFFSET + b] & PORT_PINCFG_INEN)
            inen |= 1u << b;
    if (pi == iobus_pi) {
        /* the IOBUS reads the input synchronisers: live for pins sampled continuously (CTRL.SAMPLING), the value
         * of the last APB read for pins sampled on demand (the reset state) */
        uint32_t cont = port_ctrl(m, (int)g);
        *v = ((s->lvl[g] & cont) | (s->sampled[g] & ~cont)) & inen;
    } else {
        if (s->sampled[g] != s->lvl[g]) {
            s->sampled[g] = s->lvl[g];   /* an APB read clocks the on-demand synchronisers */
            sam_activity(m);
        }
        *v = s->lvl[g] & inen;
    }
    return SAM_DONE;
}

static void port_config_write(sam_mcu_t *m, int g, uint32_t wc)
{
    /* WRCONFIG: PINMASK selects pins of the half HWSEL names; WRPINCFG / WRPMUX update their PINCFG / PMUX */
    uint32_t mask = wc & 0xFFFFu, base = wc & PORT_WRCONFIG_HWSEL ? 16u : 0u;
    for (uint32_t k = 0; k < 16; k++) {
        if (!(mask >> k & 1u))
            continue;
        uint32_t pin = base + k;
        uint8_t *cfg = &grp(m, g)[PORT_PINCFG_OFFSET + pin];
        if (wc & PORT_WRCONFIG_WRPINCFG)
            *cfg = (uint8_t)(((wc & PORT_WRCONFIG_PMUXEN) ? PORT_PINCFG_PMUXEN : 0) |
                             ((wc & PORT_WRCONFIG_INEN) ? PORT_PINCFG_INEN : 0) |
                             ((wc & PORT_WRCONFIG_PULLEN) ? PORT_PINCFG_PULLEN : 0) |
                             ((wc & PORT_WRCONFIG_DRVSTR) ? PORT_PINCFG_DRVSTR : 0));
        if (wc & PORT_WRCONFIG_WRPMUX) {
            uint8_t *pm = &grp(m, g)[PORT_PMUX_OFFSET + (pin >> 1)];
            uint8_t val = (uint8_t)((wc >> PORT_WRCONFIG_PMUX_Pos) & 15u);
            *pm = pin & 1 ? (uint8_t)((*pm & 0x0F) | val << 4) : (uint8_t)((*pm & 0xF0) | val);
        }
    }
}

static int port_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset, g = off / 0x80, r = off % 0x80;
    sam_world_pins_will_change(m);
    if (r == PORT_WRCONFIG_OFFSET) {
        port_config_write(m, (int)g, v & mask);
        sam_activity(m);
    } else {
        sam_generic_write(m, ri, v, mask);
    }
    port_levels(m, (int)g);
    if (r >= PORT_PMUX_OFFSET || r == PORT_WRCONFIG_OFFSET)
        eic_lines_update(m);
    sam_world_pins_changed(m);
    return SAM_DONE;
}

const sam_model_t sam_model_port = {"Port", port_reset, NULL, port_read, port_write, NULL};

/* ================================================================ EIC */

typedef struct {
    int8_t line_pin[16];   /* pin feeding each line through PMUX A, -1 */
    uint8_t in[16];        /* line input levels */
} eic_t;

static uint32_t eic_reg(sam_mcu_t *m, uint32_t off) { return rd32(m->regs[eic_pi] + off); }

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
    uint32_t v = rd32(f) | 1u << line;
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

static void eic_lines_update(sam_mcu_t *m)
{
    port_tables();
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

static void eic_reset(sam_mcu_t *m, int pi)
{
    port_tables();
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
            eic_lines_update(m);
            eic_irq(m);
            sam_activity(m);
            return SAM_DONE;
        }
        sam_generic_write(m, ri, v, mask);
        eic_lines_update(m);
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

/* ================================================================ TC (COUNT16) */

typedef struct {
    uint64_t sync_until;   /* SYNCBUSY until */
    int pending_enable;    /* ENABLE written: counting starts when the write has synchronised */
    int running;
    uint64_t tick;         /* tu per count */
    uint64_t tb;           /* a count boundary ... */
    uint32_t cb;           /* ... and the count there */
    uint64_t t_wrap;       /* next overflow */
    int gclk_id;
} tc_t;

static const int TC_PRESC[8] = {1, 2, 4, 8, 16, 64, 256, 1024};

static uint32_t tc_reg(sam_mcu_t *m, int pi, uint32_t off, int size)
{
    const uint8_t *p = m->regs[pi] + off;
    return size == 1 ? p[0] : size == 2 ? (uint32_t)p[0] | (uint32_t)p[1] << 8 : rd32(p);
}

static int tc_view(sam_mcu_t *m, int pi)
{
    /* views in header order: COUNT8, COUNT16, COUNT32; CTRLA.MODE 0 = COUNT16, 1 = COUNT8, 2 = COUNT32 */
    uint32_t mode = (tc_reg(m, pi, TC_CTRLA_OFFSET, 2) >> TC_CTRLA_MODE_Pos) & 3u;
    return mode == 0 ? 2 : mode == 1 ? 1 : 3;
}

static uint32_t tc_top(sam_mcu_t *m, int pi)
{
    uint32_t wg = (tc_reg(m, pi, TC_CTRLA_OFFSET, 2) >> TC_CTRLA_WAVEGEN_Pos) & 3u;
    return wg == TC_CTRLA_WAVEGEN_MFRQ_Val || wg == TC_CTRLA_WAVEGEN_MPWM_Val ? tc_reg(m, pi, TC_COUNT16_CC_OFFSET, 2)
                                                                             : 0xFFFFu;
}

static uint32_t tc_count(sam_mcu_t *m, tc_t *s, int pi, uint64_t t)
{
    if (!s->running || t < s->tb)
        return s->cb;
    uint64_t c = s->cb + (t - s->tb) / s->tick;
    uint64_t top = tc_top(m, pi);
    if (s->cb <= top)
        return (uint32_t)(c <= top ? c : (c - top - 1) % (top + 1));
    return (uint32_t)(c <= 0xFFFFu ? c : (c - 0x10000u) % (top + 1));
}

static void tc_schedule(sam_mcu_t *m, int pi)
{
    tc_t *s = m->pst[pi];
    uint64_t t = SAM_NEVER;
    if (s->running) {
        uint64_t top = tc_top(m, pi);
        uint64_t to_wrap = (s->cb <= top ? top + 1u : 0x10000u) - s->cb;
        s->t_wrap = s->tb + to_wrap * s->tick;
        t = s->t_wrap;
    }
    if (s->sync_until > sam_now(m) && s->sync_until < t)
        t = s->sync_until;
    sam_slot_set(m, pi, t);
}

/* re-anchor the counter at time t (its count keeps running) */
static void tc_anchor(sam_mcu_t *m, tc_t *s, int pi, uint64_t t)
{
    if (!s->running)
        return;
    uint32_t c = tc_count(m, s, pi, t);
    uint64_t into = (t - s->tb) % s->tick;
    s->tb = t - into;
    s->cb = c;
}

static void tc_irq(sam_mcu_t *m, int pi)
{
    uint32_t f = tc_reg(m, pi, TC_INTFLAG_OFFSET, 1) & tc_reg(m, pi, TC_INTENSET_OFFSET, 1);
    sam_irq_level(m, sam_periphs[pi].irq, f != 0);
}

static void tc_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(tc_t));
    tc_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    /* TC3..TC5 share generic clock channels: TCC2_TC3 (TC3) and TC4_TC5 */
    s->gclk_id = !strcmp(sam_periphs[pi].name, "TC3") ? TC3_GCLK_ID : TC4_GCLK_ID;
    sam_slot_set(m, pi, SAM_NEVER);
}

static void tc_sync(sam_mcu_t *m, tc_t *s)
{
    uint64_t hz = sam_gclk_hz(m, s->gclk_id);
    uint64_t now = sam_now(m);
    if (now < s->sync_until) {   /* a write while synchronising stalls the bus */
        if (s->sync_until == SAM_NEVER) {
            sam_fail(m, "write to a TC synchronising without a clock: the bus would stall forever");
            return;
        }
        m->t += s->sync_until - now;
        now = s->sync_until;
    }
    s->sync_until = hz ? now + (SYNC_GCLK_CYCLES * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
}

static void tc_start(sam_mcu_t *m, int pi, uint64_t t)
{
    tc_t *s = m->pst[pi];
    uint32_t presc = (uint32_t)TC_PRESC[(tc_reg(m, pi, TC_CTRLA_OFFSET, 2) >> TC_CTRLA_PRESCALER_Pos) & 7u];
    s->tick = tu_per_tick(m, sam_gclk_hz(m, s->gclk_id), presc, sam_periphs[pi].name);
    if (!s->tick)
        return;   /* no clock: it never counts */
    s->running = 1;
    s->tb = t;
    s->cb = tc_reg(m, pi, TC_COUNT16_COUNT_OFFSET, 2);
}

static int tc_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    tc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    if (off == TC_STATUS_OFFSET) {
        *v = (sam_now(m) < s->sync_until ? TC_STATUS_SYNCBUSY : 0) | (s->running ? 0 : TC_STATUS_STOP);
        return SAM_DONE;
    }
    if (off == TC_COUNT16_COUNT_OFFSET && tc_view(m, pi) == 2) {
        *v = tc_count(m, s, pi, sam_now(m));
        sam_activity(m);   /* changes with time */
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int tc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    tc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    v &= mask;
    if (off == TC_CTRLA_OFFSET) {
        if (v & TC_CTRLA_SWRST) {
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            for (unsigned r = sam_periphs[pi].reg0; r < sam_periphs[pi].reg1; r++)
                if (sam_regs[r].view == 2 && sam_regs[r].kind == SAM_KIND_PLAIN)
                    sam_reg_put(m, (int)r, sam_regs[r].reset);
            tc_reset(m, pi);
            tc_sync(m, s);
            tc_irq(m, pi);
            tc_schedule(m, pi);
            sam_activity(m);
            return SAM_DONE;
        }
        uint32_t old = tc_reg(m, pi, TC_CTRLA_OFFSET, 2);
        tc_sync(m, s);
        sam_generic_write(m, ri, v, mask);
        uint32_t nv = tc_reg(m, pi, TC_CTRLA_OFFSET, 2);
        if ((nv & TC_CTRLA_ENABLE) && !(old & TC_CTRLA_ENABLE)) {
            if (tc_view(m, pi) != 2) {
                sam_fail(m, "%s enabled in 8- or 32-bit mode: only COUNT16 is modelled", sam_periphs[pi].name);
                return SAM_DONE;
            }
            s->pending_enable = 1;
        } else if (!(nv & TC_CTRLA_ENABLE) && (old & TC_CTRLA_ENABLE)) {
            if (s->running) {
                uint32_t c = tc_count(m, s, pi, now);
                sam_reg_put(m, sam_reg_index(pi, "COUNT16.COUNT"), c);   /* stopping keeps the count */
            }
            s->running = 0;
            s->pending_enable = 0;
        }
        tc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off == TC_CTRLBSET_OFFSET && (v & ~TC_CTRLBSET_DIR)) {
        sam_fail(m, "%s.CTRLBSET = 0x%x: one-shot and commands are not modelled", sam_periphs[pi].name, v);
        return SAM_DONE;
    }
    if ((off == TC_CTRLBSET_OFFSET && (v & TC_CTRLBSET_DIR)) || (off == TC_CTRLC_OFFSET && v) ||
        (off == TC_EVCTRL_OFFSET && v) || (off == TC_READREQ_OFFSET && (v & TC_READREQ_RCONT))) {
        sam_fail(m, "%s = 0x%x: counting down, capture, events and continuous read are not modelled",
                 sam_regs[ri].name, v);
        return SAM_DONE;
    }
    if (off == TC_COUNT16_CC_OFFSET || off == TC_COUNT16_CC_OFFSET + 2 || off == TC_COUNT16_COUNT_OFFSET) {
        tc_anchor(m, s, pi, now);
        tc_sync(m, s);
        sam_generic_write(m, ri, v, mask);
        if (off == TC_COUNT16_COUNT_OFFSET && s->running) {
            s->tb = now;
            s->cb = v & 0xFFFFu;
        }
        tc_schedule(m, pi);
        return SAM_DONE;
    }
    sam_generic_write(m, ri, v, mask);
    if (off == TC_INTFLAG_OFFSET || off == TC_INTENSET_OFFSET || off == TC_INTENCLR_OFFSET)
        tc_irq(m, pi);
    return SAM_DONE;
}

static void tc_fire(sam_mcu_t *m, int pi)
{
    tc_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    if (s->pending_enable && now >= s->sync_until) {
        s->pending_enable = 0;
        tc_start(m, pi, now);
    }
    if (s->running && now >= s->t_wrap) {
        s->tb = s->t_wrap;
        s->cb = 0;
        uint8_t *f = m->regs[pi] + TC_INTFLAG_OFFSET;
        uint32_t wg = (tc_reg(m, pi, TC_CTRLA_OFFSET, 2) >> TC_CTRLA_WAVEGEN_Pos) & 3u;
        *f |= TC_INTFLAG_OVF;
        if (wg == TC_CTRLA_WAVEGEN_MFRQ_Val)
            *f |= TC_INTFLAG_MC0;   /* the match with CC0 that clears the counter */
        tc_irq(m, pi);
    }
    tc_schedule(m, pi);
}

/* fault injection: the TC's generic clock is lost; it stops counting and never restarts */
void sam_tc_stop_clock(sam_mcu_t *m, const char *name)
{
    int pi = sam_periph_index(name);
    tc_t *s = pi >= 0 ? m->pst[pi] : NULL;
    if (!s)
        return;
    s->running = 0;
    s->pending_enable = 0;
    s->gclk_id = -1;
    sam_slot_set(m, pi, SAM_NEVER);
}

const sam_model_t sam_model_tc = {"Tc", tc_reset, tc_view, tc_read, tc_write, tc_fire};

/* ================================================================ TCC (normal PWM) */

typedef struct {
    uint64_t sync_until;
    uint32_t sync_bits;
    int pending_enable;
    int running;
    uint64_t tick, t0, period;   /* tu per count; the counter was 0 at t0; (PER+1) counts in tu */
    uint32_t per;
    uint32_t cc[4], ccb[4];
    uint64_t t_apply[4];         /* the UPDATE at which ccb becomes cc (SAM_NEVER: none pending) */
    int nch;
    int gclk_id;
} tcc_t;

static int tcc_index(int pi) { return sam_periphs[pi].name[3] - '0'; }

static uint32_t tcc_reg(sam_mcu_t *m, int pi, uint32_t off) { return rd32(m->regs[pi] + off); }

static void tcc_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(tcc_t));
    tcc_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    int k = tcc_index(pi);
    s->nch = k == 0 ? 4 : 2;
    s->gclk_id = k == 2 ? TCC2_GCLK_ID : TCC0_GCLK_ID;   /* TCC0 and TCC1 share one channel */
    s->per = 0xFFFFFFu;
    for (int c = 0; c < 4; c++)
        s->t_apply[c] = SAM_NEVER;
    sam_slot_set(m, pi, SAM_NEVER);
}

/* the next UPDATE (counter wrap) after t */
static uint64_t tcc_next_update(tcc_t *s, uint64_t t)
{
    if (!s->running)
        return SAM_NEVER;
    if (t < s->t0)
        return s->t0;
    return s->t0 + ((t - s->t0) / s->period + 1u) * s->period;
}

static void tcc_commit(tcc_t *s, uint64_t t)
{
    for (int c = 0; c < s->nch; c++)
        if (t >= s->t_apply[c]) {
            s->cc[c] = s->ccb[c];
            s->t_apply[c] = SAM_NEVER;
        }
}

static void tcc_sync(sam_mcu_t *m, tcc_t *s, uint32_t bits)
{
    uint64_t hz = sam_gclk_hz(m, s->gclk_id), now = sam_now(m);
    if (now < s->sync_until && (s->sync_bits & bits)) {
        if (s->sync_until == SAM_NEVER) {
            sam_fail(m, "write to a TCC register synchronising without a clock: the bus would stall forever");
            return;
        }
        m->t += s->sync_until - now;
        now = s->sync_until;
    }
    if (now >= s->sync_until)
        s->sync_bits = 0;
    s->sync_bits |= bits;
    s->sync_until = hz ? now + (SYNC_GCLK_CYCLES * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
}

static void tcc_schedule(sam_mcu_t *m, int pi)
{
    tcc_t *s = m->pst[pi];
    uint64_t t = SAM_NEVER;
    if (s->sync_until > sam_now(m))
        t = s->sync_until;
    sam_slot_set(m, pi, t);
}

uint64_t sam_tcc_high(sam_mcu_t *m, int tcc, int wo, uint64_t t0, uint64_t t1, uint64_t *top)
{
    int pi = tcc >= 0 && tcc < 3 ? sam_idx.tcc[tcc] : -1;
    tcc_t *s = pi >= 0 ? m->pst[pi] : NULL;
    *top = 1;
    if (!s || !s->running || t1 <= t0)
        return 0;
    int c = wo % s->nch;
    uint64_t per = (uint64_t)s->per + 1u;
    uint64_t d_old = s->cc[c] >= per ? per : s->cc[c], d_new = s->ccb[c] >= per ? per : s->ccb[c];
    uint64_t ta = s->t_apply[c];
    uint64_t start = t0 < s->t0 ? s->t0 : t0;
    *top = per;
    if (start >= t1)
        return 0;
    /* the mean of the waveform over whole periods: CC/(PER+1) of the time (CCB takes over at its period end) */
    if (ta <= start)
        return d_new * (t1 - start);
    if (ta >= t1)
        return d_old * (t1 - start);
    return d_old * (ta - start) + d_new * (t1 - ta);
}

static int tcc_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    tcc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    tcc_commit(s, now);
    if (off == TCC_SYNCBUSY_OFFSET) {
        *v = now < s->sync_until ? s->sync_bits : 0;
        return SAM_DONE;
    }
    if (off == TCC_STATUS_OFFSET) {
        uint32_t st = s->running ? 0 : TCC_STATUS_STOP;
        for (int c = 0; c < s->nch; c++)
            if (s->t_apply[c] != SAM_NEVER)
                st |= TCC_STATUS_CCBV0 << c;
        *v = st;
        return SAM_DONE;
    }
    if (off >= TCC_CC_OFFSET && off < TCC_CC_OFFSET + 16) {
        *v = s->cc[(off - TCC_CC_OFFSET) / 4];
        return SAM_DONE;
    }
    if (off >= TCC_CCB_OFFSET && off < TCC_CCB_OFFSET + 16) {
        *v = s->ccb[(off - TCC_CCB_OFFSET) / 4];
        return SAM_DONE;
    }
    if (off == TCC_COUNT_OFFSET) {
        *v = s->running && now >= s->t0 ? (uint32_t)(((now - s->t0) % s->period) / s->tick) : 0;
        sam_activity(m);
        return SAM_DONE;
    }
    if (off == TCC_INTFLAG_OFFSET)
        return SAM_UNCOVERED;   /* the overflow and match flags are not tracked (no TCC interrupt is modelled) */
    return SAM_GENERIC;
}

static int tcc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    tcc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    v &= mask;
    sam_world_tcc_will_change(m, tcc_index(pi));   /* the motors integrate up to now with the old duty */
    tcc_commit(s, now);
    if (off == TCC_CTRLA_OFFSET) {
        if (v & TCC_CTRLA_SWRST) {
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            for (unsigned r = sam_periphs[pi].reg0; r < sam_periphs[pi].reg1; r++)
                if (sam_regs[r].kind == SAM_KIND_PLAIN)
                    sam_reg_put(m, (int)r, sam_regs[r].reset);
            tcc_reset(m, pi);
            tcc_sync(m, s, TCC_SYNCBUSY_SWRST);
            tcc_schedule(m, pi);
            sam_activity(m);
            return SAM_DONE;
        }
        uint32_t old = tcc_reg(m, pi, TCC_CTRLA_OFFSET);
        if (v & (0xFu << 24)) {
            sam_fail(m, "%s capture channels (CTRLA.CPTEN) are not modelled", sam_periphs[pi].name);
            return SAM_DONE;
        }
        tcc_sync(m, s, TCC_SYNCBUSY_ENABLE);
        sam_generic_write(m, ri, v, mask);
        uint32_t nv = tcc_reg(m, pi, TCC_CTRLA_OFFSET);
        if ((nv & TCC_CTRLA_ENABLE) && !(old & TCC_CTRLA_ENABLE)) {
            uint32_t wave = tcc_reg(m, pi, TCC_WAVE_OFFSET);
            if ((wave & TCC_WAVE_WAVEGEN_Msk) != TCC_WAVE_WAVEGEN_NPWM || (wave & ~TCC_WAVE_WAVEGEN_Msk)) {
                sam_fail(m, "%s enabled with WAVE = 0x%x: only normal PWM (NPWM, no polarity or ramp options) is "
                         "modelled", sam_periphs[pi].name, wave);
                return SAM_DONE;
            }
            s->pending_enable = 1;
        } else if (!(nv & TCC_CTRLA_ENABLE) && (old & TCC_CTRLA_ENABLE)) {
            s->running = 0;
            s->pending_enable = 0;
        }
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off == TCC_WAVE_OFFSET) {
        tcc_sync(m, s, TCC_SYNCBUSY_WAVE);
        return SAM_GENERIC;
    }
    if (off == TCC_PER_OFFSET) {
        if (s->running) {
            sam_fail(m, "%s.PER written while counting: not modelled", sam_periphs[pi].name);
            return SAM_DONE;
        }
        tcc_sync(m, s, TCC_SYNCBUSY_PER);
        s->per = v & 0xFFFFFFu;
        sam_generic_write(m, ri, v, mask);
        return SAM_DONE;
    }
    if (off >= TCC_CC_OFFSET && off < TCC_CC_OFFSET + 16) {
        int c = (int)(off - TCC_CC_OFFSET) / 4;
        tcc_sync(m, s, TCC_SYNCBUSY_CC0 << c);
        s->cc[c] = v & 0xFFFFFFu;
        s->ccb[c] = s->cc[c];
        s->t_apply[c] = SAM_NEVER;
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off >= TCC_CCB_OFFSET && off < TCC_CCB_OFFSET + 16) {
        int c = (int)(off - TCC_CCB_OFFSET) / 4;
        tcc_sync(m, s, TCC_SYNCBUSY_CCB0 << c);
        s->ccb[c] = v & 0xFFFFFFu;
        /* buffered: takes effect at the next UPDATE (the counter's wrap) after the write has synchronised */
        s->t_apply[c] = (tcc_reg(m, pi, TCC_CTRLBSET_OFFSET) & TCC_CTRLBSET_LUPD) ? SAM_NEVER
                                                                                   : tcc_next_update(s, s->sync_until);
        if (!s->running)
            s->t_apply[c] = SAM_NEVER;
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if ((off == TCC_CTRLBSET_OFFSET && (v & ~TCC_CTRLBSET_LUPD)) || (off == TCC_PERB_OFFSET) ||
        ((off == TCC_WEXCTRL_OFFSET || off == TCC_DRVCTRL_OFFSET || off == TCC_EVCTRL_OFFSET ||
          off == TCC_FCTRLA_OFFSET || off == TCC_FCTRLB_OFFSET || off == TCC_PATT_OFFSET ||
          off == TCC_INTENSET_OFFSET) &&
         v)) {
        sam_fail(m, "%s = 0x%x: not modelled (only normal PWM with buffered compare values)", sam_regs[ri].name, v);
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static void tcc_fire(sam_mcu_t *m, int pi)
{
    tcc_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    if (s->pending_enable && now >= s->sync_until) {
        uint32_t presc = (uint32_t)TC_PRESC[(tcc_reg(m, pi, TCC_CTRLA_OFFSET) >> TCC_CTRLA_PRESCALER_Pos) & 7u];
        sam_world_tcc_will_change(m, tcc_index(pi));
        s->pending_enable = 0;
        s->tick = tu_per_tick(m, sam_gclk_hz(m, s->gclk_id), presc, sam_periphs[pi].name);
        if (s->tick) {
            s->running = 1;
            s->t0 = now;
            s->period = ((uint64_t)s->per + 1u) * s->tick;
            for (int c = 0; c < s->nch; c++)
                if (s->ccb[c] != s->cc[c])
                    s->t_apply[c] = tcc_next_update(s, now);
        }
    }
    tcc_schedule(m, pi);
}

const sam_model_t sam_model_tcc = {"Tcc", tcc_reset, NULL, tcc_read, tcc_write, tcc_fire};
