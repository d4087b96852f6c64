/* Clocks and system: PM (bus clocks, reset cause), SYSCTRL (oscillators), GCLK (generators, channels), NVMCTRL, WDT. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

/* The board: a Seeeduino XIAO has a 32.768 kHz crystal on XIN32/XOUT32 (PA00, PA01) and no main crystal: XOSC32K
 * becomes ready after its STARTUP time, XOSC never does. The DFLL in closed loop runs at MUL x its reference; within
 * DFLL_NOMINAL_TOL of 48 MHz (1465 x 32768 Hz = 48.005 MHz, +107 ppm, is) it is taken as exactly 48 MHz: the boards'
 * clocks are nominal, oscillator tolerance and drift are not modelled. Open loop and USB clock recovery: 48 MHz. */
#define HZ_OSCULP32K 32768u
#define HZ_OSC32K 32768u
#define HZ_OSC8M 8000000u
#define HZ_DFLL_OPEN 48000000u
#define HZ_USB_SOF 1000u
#define HZ_DFLL_NOMINAL 48000000u
#define DFLL_NOMINAL_TOL 1e-3
/* XOSC32K start-up (SYSCTRL.XOSC32K.STARTUP): OSCULP32K cycles, plus 3 for synchronisation (DS40001882 table
 * "Start-Up Time for 32kHz External Crystal Oscillator": 0x6 is 65536 cycles, 2000092 us) */
static const uint32_t XOSC32K_STARTUP[8] = {1, 32, 2048, 4096, 16384, 32768, 65536, 131072};
/* write-synchronisation of a slow peripheral: a few of its generic clock's cycles (DS40001882 "Synchronization") */
#define SYNC_GCLK_CYCLES 3u

#define NGEN 9
#define NCHAN 0x25

static uint32_t field_get(uint32_t v, uint32_t pos, uint32_t width) { return (v >> pos) & ((1u << width) - 1u); }

/* ---------------------------------------------------------------- PM */

/* (register index, mask) of a peripheral's bus clock enable, from the PM APBxMASK field of the same name */
static int apb_reg[SAM_MAX_PERIPH];
static uint32_t apb_mask[SAM_MAX_PERIPH];
static int apb_ready;

static void apb_table(void)
{
    if (apb_ready)
        return;
    int pm = sam_periph_index("PM");
    const char *regs[3] = {"APBAMASK", "APBBMASK", "APBCMASK"};
    for (unsigned pi = 0; pi < sam_nperiphs; pi++) {
        apb_reg[pi] = -1;
        const char *name = sam_periphs[pi].name;
        if (!strcmp(name, "PORT_IOBUS"))
            name = "PORT";
        for (int k = 0; k < 3; k++) {
            int ri = sam_reg_index(pm, regs[k]);
            const sam_field_t *f = ri >= 0 ? sam_field(ri, name) : NULL;
            if (f) {
                apb_reg[pi] = ri;
                apb_mask[pi] = 1u << f->pos;
            }
        }
    }
    apb_ready = 1;
}

int sam_apb_on(sam_mcu_t *m, int pi)
{
    apb_table();
    if (apb_reg[pi] < 0)
        return 1;   /* not gated by PM (system control space, the DSU's debug side) */
    return (sam_reg_get(m, apb_reg[pi]) & apb_mask[pi]) != 0;
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

/* ---------------------------------------------------------------- SYSCTRL */

static uint32_t sysctrl_get(sam_mcu_t *m, uint32_t off)
{
    const uint8_t *p = m->regs[sam_idx.sysctrl] + off;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t sam_dfll_hz(sam_mcu_t *m)
{
    uint32_t ctrl = sysctrl_get(m, SYSCTRL_DFLLCTRL_OFFSET);
    if (!(ctrl & SYSCTRL_DFLLCTRL_ENABLE))
        return 0;
    if (!(ctrl & SYSCTRL_DFLLCTRL_MODE))
        return HZ_DFLL_OPEN;
    uint32_t mul = sysctrl_get(m, SYSCTRL_DFLLMUL_OFFSET) & 0xFFFFu;
    uint64_t hz = ctrl & SYSCTRL_DFLLCTRL_USBCRM ? (uint64_t)mul * HZ_USB_SOF
                                                 : (uint64_t)mul * sam_gclk_hz(m, SYSCTRL_GCLK_ID_DFLL48);
    if (fabs((double)hz - HZ_DFLL_NOMINAL) <= HZ_DFLL_NOMINAL * DFLL_NOMINAL_TOL)
        hz = HZ_DFLL_NOMINAL;
    return hz;
}

typedef struct {
    uint64_t xosc32k_ready;   /* when XOSC32K's start-up ends (SAM_NEVER: off) */
} sysctrl_t;

static void sysctrl_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(sysctrl_t));
    ((sysctrl_t *)m->pst[pi])->xosc32k_ready = SAM_NEVER;
}

static int sysctrl_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    sysctrl_t *s = m->pst[pi];
    if (sam_regs[ri].offset == SYSCTRL_PCLKSR_OFFSET) {
        uint32_t r = SYSCTRL_PCLKSR_DFLLRDY | SYSCTRL_PCLKSR_BOD33RDY | SYSCTRL_PCLKSR_B33SRDY;
        if (sam_now(m) >= s->xosc32k_ready)
            r |= SYSCTRL_PCLKSR_XOSC32KRDY;
        if (sysctrl_get(m, SYSCTRL_OSC32K_OFFSET) & SYSCTRL_OSC32K_ENABLE)
            r |= SYSCTRL_PCLKSR_OSC32KRDY;
        if (sysctrl_get(m, SYSCTRL_OSC8M_OFFSET) & SYSCTRL_OSC8M_ENABLE)
            r |= SYSCTRL_PCLKSR_OSC8MRDY;
        uint32_t dc = sysctrl_get(m, SYSCTRL_DFLLCTRL_OFFSET);
        if ((dc & SYSCTRL_DFLLCTRL_ENABLE) && (dc & SYSCTRL_DFLLCTRL_MODE))
            r |= SYSCTRL_PCLKSR_DFLLLCKF | SYSCTRL_PCLKSR_DFLLLCKC;
        *v = r;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int sysctrl_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    uint32_t off = sam_regs[ri].offset;
    if (off == SYSCTRL_INTENSET_OFFSET && (v & mask)) {
        sam_fail(m, "SYSCTRL interrupts are not modelled (INTENSET = 0x%x)", v);
        return SAM_DONE;
    }
    if (off == SYSCTRL_DPLLCTRLA_OFFSET && (v & mask & SYSCTRL_DPLLCTRLA_ENABLE)) {
        sam_fail(m, "the FDPLL96M is not modelled");
        return SAM_DONE;
    }
    uint32_t old = sam_reg_get(m, ri);
    uint32_t nv = (old & ~mask) | (v & mask);
    if (sam_regs[ri].kind != SAM_KIND_PLAIN)
        return SAM_GENERIC;
    sam_reg_put(m, ri, nv);
    if (off == SYSCTRL_XOSC32K_OFFSET) {
        sysctrl_t *s = m->pst[pi];
        int on = (nv & (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN)) == (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN);
        if (on && !((old & (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN)) == (SYSCTRL_XOSC32K_ENABLE | SYSCTRL_XOSC32K_XTALEN))) {
            uint32_t cyc = XOSC32K_STARTUP[(nv >> SYSCTRL_XOSC32K_STARTUP_Pos) & 7u] + 3u;
            s->xosc32k_ready = sam_now(m) + (uint64_t)cyc * (SAM_TU_HZ / HZ_OSCULP32K);
            sam_slot_set(m, pi, s->xosc32k_ready);   /* the ready bit changes then: an event */
        } else if (!on) {
            s->xosc32k_ready = SAM_NEVER;
        }
    }
    if (nv != old) {
        sam_activity(m);
        sam_set_cpu_clock(m);   /* a source of GCLK0 may have changed */
    }
    return SAM_DONE;
}

static void sysctrl_fire(sam_mcu_t *m, int pi)
{
    (void)m;
    (void)pi;   /* a start-up ended: the event itself is what matters (PCLKSR reads change now) */
}

const sam_model_t sam_model_sysctrl = {"Sysctrl", sysctrl_reset, NULL, sysctrl_read, sysctrl_write, sysctrl_fire};

/* ---------------------------------------------------------------- GCLK */

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
    case GCLK_GENCTRL_SRC_OSCULP32K_Val: return HZ_OSCULP32K;
    case GCLK_GENCTRL_SRC_OSC32K_Val:
        return (sysctrl_get(m, SYSCTRL_OSC32K_OFFSET) & (SYSCTRL_OSC32K_ENABLE | SYSCTRL_OSC32K_EN32K)) ==
                       (SYSCTRL_OSC32K_ENABLE | SYSCTRL_OSC32K_EN32K)
                   ? HZ_OSC32K
                   : 0;
    case GCLK_GENCTRL_SRC_OSC8M_Val: {
        uint32_t o = sysctrl_get(m, SYSCTRL_OSC8M_OFFSET);
        return o & SYSCTRL_OSC8M_ENABLE ? HZ_OSC8M >> field_get(o, SYSCTRL_OSC8M_PRESC_Pos, 2) : 0;
    }
    case GCLK_GENCTRL_SRC_DFLL48M_Val: return sam_dfll_hz(m);
    case GCLK_GENCTRL_SRC_XOSC32K_Val: {
        uint32_t x = sysctrl_get(m, SYSCTRL_XOSC32K_OFFSET);
        sysctrl_t *s = m->pst[sam_idx.sysctrl];
        return (x & SYSCTRL_XOSC32K_EN32K) && s && sam_now(m) >= s->xosc32k_ready ? 32768u : 0;
    }
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
    default: return 0;   /* XOSC, GCLKIN: not fitted on the XIAO; FDPLL96M: not modelled */
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

/* ---------------------------------------------------------------- NVMCTRL */

static int nvm_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    switch (sam_regs[ri].offset) {
    case NVMCTRL_PARAM_OFFSET: *v = NVMCTRL_PARAM_NVMP(4096) | NVMCTRL_PARAM_PSZ(3); return SAM_DONE;   /* 256 KiB */
    case NVMCTRL_INTFLAG_OFFSET: *v = NVMCTRL_INTFLAG_READY; return SAM_DONE;
    case NVMCTRL_STATUS_OFFSET: *v = 0; return SAM_DONE;
    default: return SAM_GENERIC;
    }
}

static int nvm_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if (off == NVMCTRL_CTRLA_OFFSET && (v & mask)) {
        sam_fail(m, "NVM command 0x%x: programming the flash is not modelled", v & 0x7Fu);
        return SAM_DONE;
    }
    if (off == NVMCTRL_CTRLB_OFFSET) {
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | (v & mask));
        m->rws = field_get(sam_reg_get(m, ri), NVMCTRL_CTRLB_RWS_Pos, 4);
        if (sam_reg_get(m, ri) & NVMCTRL_CTRLB_CACHEDIS)
            sam_fail(m, "NVMCTRL.CTRLB.CACHEDIS: running without the NVM cache is not modelled");
        sam_activity(m);
        return SAM_DONE;
    }
    if (off == NVMCTRL_INTENSET_OFFSET && (v & mask)) {
        sam_fail(m, "NVMCTRL interrupts are not modelled");
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static void nvm_reset(sam_mcu_t *m, int pi)
{
    (void)pi;
    m->rws = 0;
}

const sam_model_t sam_model_nvmctrl = {"Nvmctrl", nvm_reset, NULL, nvm_read, nvm_write, NULL};

/* ---------------------------------------------------------------- WDT */

typedef struct {
    uint64_t sync_until;   /* SYNCBUSY until (SAM_NEVER: its clock is off) */
    int pending_enable, pending_clear;
    uint8_t ctrl_pending;
    uint64_t timeout;      /* SAM_NEVER when not counting */
} wdt_t;

static uint64_t wdt_clock_tu(sam_mcu_t *m, uint64_t cycles)
{
    uint64_t hz = sam_gclk_hz(m, WDT_GCLK_ID);
    return hz ? cycles * SAM_TU_HZ / hz : SAM_NEVER;
}

static void wdt_schedule(sam_mcu_t *m, int pi)
{
    wdt_t *s = m->pst[pi];
    uint64_t t = s->timeout;
    if (s->sync_until && s->sync_until < t)   /* 0: not synchronising */
        t = s->sync_until;
    sam_slot_set(m, pi, t);
}

static void wdt_restart(sam_mcu_t *m, int pi, uint64_t now)
{
    wdt_t *s = m->pst[pi];
    int ri = sam_idx.wdt_config;
    uint32_t per = sam_reg_get(m, ri) & 0xFu;
    if (per > 0xB) {
        sam_fail(m, "WDT.CONFIG.PER = 0x%x: reserved", per);
        return;
    }
    uint64_t d = wdt_clock_tu(m, 8ull << per);
    s->timeout = d == SAM_NEVER ? SAM_NEVER : now + d;
}

static void wdt_reset_model(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(wdt_t));
    wdt_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    s->timeout = SAM_NEVER;
    s->sync_until = 0;
}

static int wdt_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    wdt_t *s = m->pst[pi];
    if (sam_regs[ri].offset == WDT_STATUS_OFFSET) {
        *v = sam_now(m) < s->sync_until ? WDT_STATUS_SYNCBUSY : 0;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static void wdt_sync(sam_mcu_t *m, int pi)
{
    wdt_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    if (now < s->sync_until) {
        /* a write to a register still synchronising stalls the bus until it completes */
        if (s->sync_until == SAM_NEVER) {
            sam_fail(m, "write to the WDT while it synchronises without a clock: the bus would stall forever");
            return;
        }
        m->t += s->sync_until - now;
        now = s->sync_until;
    }
    uint64_t d = wdt_clock_tu(m, SYNC_GCLK_CYCLES);
    s->sync_until = d == SAM_NEVER ? SAM_NEVER : now + d;
}

static int wdt_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    wdt_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    v &= mask;
    if (off == WDT_CLEAR_OFFSET) {
        if (v != WDT_CLEAR_CLEAR_KEY) {
            sam_note(m, "%s: watchdog cleared with a wrong key (0x%02x): system reset", m->name, v);
            sam_mcu_system_reset(m, PM_RCAUSE_WDT);
            return SAM_DONE;
        }
        wdt_sync(m, pi);
        s->pending_clear = 1;
    } else if (off == WDT_CTRL_OFFSET) {
        if (v & (WDT_CTRL_WEN | WDT_CTRL_ALWAYSON)) {
            sam_fail(m, "WDT.CTRL = 0x%x: window mode and always-on are not modelled", v);
            return SAM_DONE;
        }
        wdt_sync(m, pi);
        s->ctrl_pending = (uint8_t)(v | 0x80u);
    } else if (off == WDT_CONFIG_OFFSET) {
        wdt_sync(m, pi);
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | v);
    } else if (off == WDT_INTENSET_OFFSET && v) {
        sam_fail(m, "the WDT early warning interrupt is not modelled");
        return SAM_DONE;
    } else if (off == WDT_EWCTRL_OFFSET) {
        wdt_sync(m, pi);
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | v);
    } else {
        return SAM_GENERIC;
    }
    sam_activity(m);
    wdt_schedule(m, pi);
    return SAM_DONE;
}

static void wdt_fire(sam_mcu_t *m, int pi)
{
    wdt_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    if (now >= s->sync_until && s->sync_until != 0) {
        /* the synchronised writes take effect */
        s->sync_until = 0;
        int ci = sam_idx.wdt_ctrl;
        if (s->ctrl_pending & 0x80u) {
            uint32_t old = sam_reg_get(m, ci), nv = s->ctrl_pending & 0x7Fu;
            sam_reg_put(m, ci, nv);
            s->ctrl_pending = 0;
            if ((nv & WDT_CTRL_ENABLE) && !(old & WDT_CTRL_ENABLE))
                wdt_restart(m, pi, now);
            else if (!(nv & WDT_CTRL_ENABLE))
                s->timeout = SAM_NEVER;
        }
        if (s->pending_clear) {
            s->pending_clear = 0;
            if (sam_reg_get(m, ci) & WDT_CTRL_ENABLE)
                wdt_restart(m, pi, now);
        }
    }
    if (now >= s->timeout) {
        sam_note(m, "%s: watchdog timeout at t = %.6f s: system reset", m->name,
                       (double)now / (double)SAM_TU_HZ);
        s->timeout = SAM_NEVER;
        sam_mcu_system_reset(m, PM_RCAUSE_WDT);
        return;
    }
    wdt_schedule(m, pi);
}

const sam_model_t sam_model_wdt = {"Wdt", wdt_reset_model, NULL, wdt_read, wdt_write, wdt_fire};

/* ---------------------------------------------------------------- configured but idle: ADC, DAC, PAC, DSU */

/* The Arduino core configures the ADC and DAC in init() and the images never convert: their configuration
 * registers are stored; a conversion start or an interrupt enable is an error naming it. */
static int adc_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    if (sam_regs[ri].offset == ADC_STATUS_OFFSET) {
        *v = 0;
        return SAM_DONE;
    }
    if (sam_regs[ri].offset == ADC_RESULT_OFFSET)
        return SAM_UNCOVERED;
    return SAM_GENERIC;
}

static int adc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if ((off == ADC_SWTRIG_OFFSET || off == ADC_INTENSET_OFFSET) && (v & mask)) {
        sam_fail(m, "ADC conversions are not modelled (%s = 0x%x)", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    if (off == ADC_CTRLA_OFFSET && (v & mask & ADC_CTRLA_ENABLE)) {
        sam_fail(m, "the ADC enabled: conversions are not modelled");
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_adc = {"Adc", NULL, NULL, adc_read, adc_write, NULL};

static int dac_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    (void)pi;
    if (sam_regs[ri].offset == DAC_STATUS_OFFSET) {
        *v = 0;
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static int dac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    uint32_t off = sam_regs[ri].offset;
    if ((off == DAC_CTRLA_OFFSET && (v & mask & DAC_CTRLA_ENABLE)) || (off == DAC_INTENSET_OFFSET && (v & mask))) {
        sam_fail(m, "the DAC output is not modelled (%s = 0x%x)", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_dac = {"Dac", NULL, NULL, dac_read, dac_write, NULL};

/* Peripheral access control: write protection is stored, not enforced (the images never set it). */
static int pac_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)pi;
    if (!strcmp(sam_regs[ri].name + strlen(sam_periphs[pi].name) + 1, "WPSET") && (v & mask)) {
        sam_fail(m, "peripheral write protection (%s = 0x%x) is not modelled", sam_regs[ri].name, v & mask);
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

const sam_model_t sam_model_pac = {"Pac", NULL, NULL, NULL, pac_write, NULL};

/* Device Service Unit: only its identification is read (a SAMD21G18A, DID from the datasheet's table). */
static int dsu_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    (void)m;
    if (!strcmp(sam_regs[ri].name + strlen(sam_periphs[pi].name) + 1, "DID")) {
        *v = 0x10010305u;
        return SAM_DONE;
    }
    return SAM_UNCOVERED;
}

static int dsu_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    (void)m;
    (void)pi;
    (void)ri;
    (void)v;
    (void)mask;
    return SAM_UNCOVERED;
}

const sam_model_t sam_model_dsu = {"Dsu", NULL, NULL, dsu_read, dsu_write, NULL};
