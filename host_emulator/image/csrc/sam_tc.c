/* TC: the 16-bit timer/counter in match-frequency mode (COUNT16): prescaler, CC0, overflow flag and interrupt, READREQ. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_vendor_gen.h"

typedef struct {
    uint64_t sync_until;   /* SYNCBUSY until */
    int pending_enable;    /* ENABLE written: counting starts when the write has synchronised */
    int running;
    uint64_t tick;         /* tu per count */
    uint64_t tb;           /* a count boundary ... */
    uint32_t cb;           /* ... and the count there */
    uint64_t t_wrap;       /* next overflow */
    int gclk_id;
    /* read synchronisation (DS40001882 30.6.6 Synchronization, 30.10.2 READREQ): COUNT and CCx live in the TC's
     * clock domain; a CPU read returns what the last read synchronisation brought over */
    int rs_pending;        /* READREQ.RREQ written: the synchronisation completes at rs_until ... */
    uint64_t rs_until;
    uint32_t rs_addr;      /* ... of the register at this offset (READREQ.ADDR) */
    int rs_cont;           /* ... with READREQ.RCONT: continuous from then on */
    int rs_live;           /* COUNT synchronised continuously: its reads are live */
    uint32_t rs_count;     /* COUNT as the last synchronisation left it (its reset value before any) */
} tc_t;

static const int TC_PRESC[8] = {1, 2, 4, 8, 16, 64, 256, 1024};

static uint32_t tc_reg(sam_mcu_t *m, int pi, uint32_t off, int size)
{
    const uint8_t *p = m->regs[pi] + off;
    return size == 1 ? p[0] : size == 2 ? (uint32_t)p[0] | (uint32_t)p[1] << 8 : sam_rd32(p);
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

/* a read synchronisation whose time has come takes the counter's value at its completion (COUNT; CCx hold what
 * was written, capture not being modelled, so theirs changes nothing). Called before anything else looks at or
 * changes the counter, so the value is the one the counter had then. */
static void tc_settle(sam_mcu_t *m, tc_t *s, int pi)
{
    if (!s->rs_pending || sam_now(m) < s->rs_until)
        return;
    s->rs_pending = 0;
    if (s->rs_addr == TC_COUNT16_COUNT_OFFSET) {
        s->rs_count = tc_count(m, s, pi, s->rs_until);
        s->rs_live = s->rs_cont;
    }
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

static void tc_sync(sam_mcu_t *m, tc_t *s, int pi)
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
        tc_settle(m, s, pi);   /* a read synchronisation the stall waited for completed first */
    }
    s->sync_until = hz ? now + (SAM_SYNC_GCLK_CYCLES * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
}

static void tc_start(sam_mcu_t *m, int pi, uint64_t t)
{
    tc_t *s = m->pst[pi];
    uint32_t presc = (uint32_t)TC_PRESC[(tc_reg(m, pi, TC_CTRLA_OFFSET, 2) >> TC_CTRLA_PRESCALER_Pos) & 7u];
    s->tick = sam_tu_per_tick(m, sam_gclk_hz(m, s->gclk_id), presc, sam_periphs[pi].name);
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
    tc_settle(m, s, pi);
    if (off == TC_STATUS_OFFSET) {
        *v = (sam_now(m) < s->sync_until ? TC_STATUS_SYNCBUSY : 0) | (s->running ? 0 : TC_STATUS_STOP);
        return SAM_DONE;
    }
    if (off == TC_COUNT16_COUNT_OFFSET && tc_view(m, pi) == 2) {
        /* DS40001882 30.6.6, 30.10.2 READREQ: the value of the last read synchronisation. Synchronised
         * continuously (RCONT), the live count: it changes with time, so its read is activity (no fast-forward past
         * it, sam_ff.c); else a constant until the next READREQ.RREQ (a write, itself activity), so it is not. */
        if (s->rs_live) {
            *v = tc_count(m, s, pi, sam_now(m));
            sam_activity(m);
        } else {
            *v = s->rs_count;
        }
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
    tc_settle(m, s, pi);
    if (off == TC_CTRLA_OFFSET) {
        if (v & TC_CTRLA_SWRST) {
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            for (unsigned r = sam_periphs[pi].reg0; r < sam_periphs[pi].reg1; r++)
                if (sam_regs[r].view == 2 && sam_regs[r].kind == SAM_KIND_PLAIN)
                    sam_reg_put(m, (int)r, sam_regs[r].reset);
            tc_reset(m, pi);
            tc_sync(m, s, pi);
            tc_irq(m, pi);
            tc_schedule(m, pi);
            sam_activity(m);
            return SAM_DONE;
        }
        uint32_t old = tc_reg(m, pi, TC_CTRLA_OFFSET, 2);
        /* PRESCSYNC, RUNSTDBY, PRESCALER, WAVEGEN, MODE: enable-protected (sam_protect.c) */
        v = sam_enable_protected(m, ri, v, mask, 0x3F0Cu | 0x60u, (old & TC_CTRLA_ENABLE) != 0);
        tc_sync(m, s, pi);
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
        (off == TC_EVCTRL_OFFSET && v)) {
        sam_fail(m, "%s = 0x%x: counting down, capture and events are not modelled", sam_regs[ri].name, v);
        return SAM_DONE;
    }
    if (off == TC_READREQ_OFFSET) {
        /* DS40001882 30.10.2 READREQ: RREQ requests the read synchronisation of the register at ADDR (only COUNT
         * and CCx can be: any other offset synchronises nothing) and sets STATUS.SYNCBUSY until it completes, the
         * time a write's synchronisation takes (a request while one is under way waits for it, as a write does);
         * RREQ reads as zero. RCONT keeps the register synchronised from the request's completion on; clearing
         * it, or pointing ADDR elsewhere, leaves the value the continuous synchronisation had last. */
        uint32_t full = (tc_reg(m, pi, TC_READREQ_OFFSET, 2) & ~mask) | v;   /* a byte write keeps the other byte */
        uint32_t addr = full & TC_READREQ_ADDR_Msk;
        if (s->rs_live && (!(full & TC_READREQ_RCONT) || addr != TC_COUNT16_COUNT_OFFSET)) {
            s->rs_count = tc_count(m, s, pi, now);
            s->rs_live = 0;
        }
        if (v & TC_READREQ_RREQ) {
            tc_sync(m, s, pi);
            s->rs_pending = 1;
            s->rs_until = s->sync_until;
            s->rs_addr = addr;
            s->rs_cont = (full & TC_READREQ_RCONT) != 0;
        }
        sam_generic_write(m, ri, v & ~TC_READREQ_RREQ, mask);
        tc_schedule(m, pi);
        sam_activity(m);
        return SAM_DONE;
    }
    if (off == TC_COUNT16_CC_OFFSET || off == TC_COUNT16_CC_OFFSET + 2 || off == TC_COUNT16_COUNT_OFFSET) {
        tc_anchor(m, s, pi, now);
        tc_sync(m, s, pi);
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
    tc_settle(m, s, pi);
    if (s->pending_enable && now >= s->sync_until) {
        s->pending_enable = 0;
        tc_start(m, pi, now);
        tc_schedule(m, pi);   /* its first wrap from the count it starts at (t_wrap was the last run's, or 0) */
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
