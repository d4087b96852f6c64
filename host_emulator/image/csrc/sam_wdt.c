/* WDT: the watchdog in normal mode, clocked from GCLK, its CLEAR key and write synchronisation, the reset on timeout. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

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
    uint64_t d = wdt_clock_tu(m, SAM_SYNC_GCLK_CYCLES);
    s->sync_until = d == SAM_NEVER ? SAM_NEVER : now + d;
}

/* CTRL.ENABLE as the enable protection sees it: written (it reads back at once) or in effect */
static int wdt_enabled(sam_mcu_t *m, int pi)
{
    const wdt_t *s = m->pst[pi];
    if (s->ctrl_pending & 0x80u)
        return (s->ctrl_pending & WDT_CTRL_ENABLE) != 0;
    return (sam_reg_get(m, sam_idx.wdt_ctrl) & WDT_CTRL_ENABLE) != 0;
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
        v = sam_enable_protected(m, ri, v, mask, 0xFFu, wdt_enabled(m, pi));
        wdt_sync(m, pi);
        sam_reg_put(m, ri, (sam_reg_get(m, ri) & ~mask) | v);
    } else if (off == WDT_INTENSET_OFFSET && v) {
        sam_fail(m, "the WDT early warning interrupt is not modelled");
        return SAM_DONE;
    } else if (off == WDT_EWCTRL_OFFSET) {
        v = sam_enable_protected(m, ri, v, mask, 0x0Fu, wdt_enabled(m, pi));
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
