/* TCC: the timer/counter for control in normal PWM, PER, CC and the buffered CCB, waveform outputs to the pins. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

static const int TCC_PRESC[8] = {1, 2, 4, 8, 16, 64, 256, 1024};

typedef struct {
    uint64_t sync_until;
    uint32_t sync_bits;
    int pending_enable;
    int running;
    uint64_t tick, t0, period;   /* tu per count; the counter was 0 at t0; (PER+1) counts in tu */
    uint32_t per;
    uint32_t cc[4], ccb[4];
    uint64_t t_apply[4];         /* the UPDATE at which ccb becomes cc (SAM_NEVER: none pending) */
    uint8_t locked[4];           /* ccb written under CTRLB.LUPD: valid (STATUS.CCBV), copied after LUPD clears */
    int nch;
    int gclk_id;
} tcc_t;

static int tcc_index(int pi) { return sam_periphs[pi].name[3] - '0'; }

static uint32_t tcc_reg(sam_mcu_t *m, int pi, uint32_t off) { return sam_rd32(m->regs[pi] + off); }

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

#define TCC_CTRLBCLR_OFFSET 0x04   /* CTRLBCLR, beside CTRLBSET (0x05): the same bits */

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
    s->sync_until = hz ? now + (SAM_SYNC_GCLK_CYCLES * SAM_TU_HZ + hz - 1) / hz : SAM_NEVER;
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
    for (int c = 0; c < s->nch; c++)
        if (now >= s->t_apply[c]) {   /* a buffered value is taken over: the motors integrate the old duty first */
            sam_world_tcc_will_change(m, tcc_index(pi));
            break;
        }
    tcc_commit(s, now);
    if (off == TCC_SYNCBUSY_OFFSET) {
        *v = now < s->sync_until ? s->sync_bits : 0;
        return SAM_DONE;
    }
    /* STATUS.CCBVn and CCn change at the UPDATE that takes a buffered value over, which is no event (tcc_commit
     * applies it when next looked at): while one is pending, a read of them is activity, so a loop() polling them is
     * never fast-forwarded past the change (sam_ff.c) */
    if (off == TCC_STATUS_OFFSET) {
        uint32_t st = s->running ? 0 : TCC_STATUS_STOP;
        for (int c = 0; c < s->nch; c++)
            if (s->t_apply[c] != SAM_NEVER || s->locked[c])
                st |= TCC_STATUS_CCBV0 << c;
        for (int c = 0; c < s->nch; c++)
            if (s->t_apply[c] != SAM_NEVER)
                sam_activity(m);
        *v = st;
        return SAM_DONE;
    }
    if (off >= TCC_CC_OFFSET && off < TCC_CC_OFFSET + 16) {
        int c = (int)(off - TCC_CC_OFFSET) / 4;
        *v = s->cc[c];
        if (c < s->nch && s->t_apply[c] != SAM_NEVER)
            sam_activity(m);
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
        s->locked[c] = 0;
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off >= TCC_CCB_OFFSET && off < TCC_CCB_OFFSET + 16) {
        int c = (int)(off - TCC_CCB_OFFSET) / 4;
        tcc_sync(m, s, TCC_SYNCBUSY_CCB0 << c);
        s->ccb[c] = v & 0xFFFFFFu;
        /* buffered: takes effect at the next UPDATE (the counter's wrap) after the write has synchronised */
        s->locked[c] = (tcc_reg(m, pi, TCC_CTRLBSET_OFFSET) & TCC_CTRLBSET_LUPD) != 0;
        s->t_apply[c] = s->locked[c] ? SAM_NEVER : tcc_next_update(s, s->sync_until);
        if (!s->running)
            s->t_apply[c] = SAM_NEVER;
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off == TCC_CTRLBCLR_OFFSET && (v & TCC_CTRLBSET_LUPD)) {
        /* 31.6.2.6 Double Buffering: with LUPD cleared, the buffers written meanwhile are copied at the next UPDATE */
        sam_generic_write(m, ri, v, mask);
        for (int c = 0; c < s->nch; c++)
            if (s->locked[c]) {
                s->locked[c] = 0;
                s->t_apply[c] = s->running ? tcc_next_update(s, now) : SAM_NEVER;
            }
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
        uint32_t presc = (uint32_t)TCC_PRESC[(tcc_reg(m, pi, TCC_CTRLA_OFFSET) >> TCC_CTRLA_PRESCALER_Pos) & 7u];
        sam_world_tcc_will_change(m, tcc_index(pi));
        s->pending_enable = 0;
        s->tick = sam_tu_per_tick(m, sam_gclk_hz(m, s->gclk_id), presc, sam_periphs[pi].name);
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
