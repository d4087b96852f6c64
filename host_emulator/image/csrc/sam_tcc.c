/* TCC: the timer/counter for control in normal PWM: the counter's phase, PER/CC and their buffers, each output's edges. */
#include <stdlib.h>
#include <string.h>
#include "sam.h"
#include "sam_world.h"
#include "sam_vendor_gen.h"

static const int TCC_PRESC[8] = {1, 2, 4, 8, 16, 64, 256, 1024};

/* The counter counts up by one every `tick` tu from 0 at `za` (the current cycle's start) to `top`, then wraps
 * (the UPDATE condition) and counts 0..PER from then on. `top` is PER except after PER was written below the count:
 * the counter then runs on to MAX before it wraps (DS40001882 31.6.2.6, Figure 31-9 "Unbuffered Single-Slope
 * Up-Counting Operation"). In NPWM an output WO[n] is set at the cycle's start and cleared when the count reaches
 * CC[n] (31.6.2.5.2): high while COUNT < CC. The buffers PERB and CCB[n] are copied on the first UPDATE after their
 * write has synchronised ("ready"), unless CTRLB.LUPD is set then (31.6.2.6 Double Buffering). */
typedef struct {
    uint64_t sync_until;
    uint32_t sync_bits;
    int pending_enable;
    int running;
    uint64_t tick;               /* tu per count */
    uint64_t t_start;            /* counting since (the outputs are low before) */
    uint64_t za;                 /* the current cycle began at za */
    uint32_t top;                /* its last count */
    uint32_t per, max;
    uint32_t cc[4];
    uint32_t perb, ccb[4];
    uint64_t ready_per, ready_cc[4];   /* the buffer is valid from then on (STATUS.PERBV, CCBVn); SAM_NEVER: not */
    int nch;
    int gclk_id;
    int rs_pending;              /* CTRLBSET.CMD = READSYNC written: COUNT is brought over at rs_at */
    uint64_t rs_at;
    uint32_t rs_count;           /* COUNT as the last read synchronisation left it (its reset value 0 before any) */
} tcc_t;

/* Enable-protected (sam_protect.c's table, DS40001882 31.8.1 CTRLA): RESOLUTION, PRESCALER, RUNSTDBY, PRESCSYNC,
 * ALOCK, CPTENn; and the whole of FCTRLA, FCTRLB, WEXCTRL, DRVCTRL, EVCTRL (31.8, each marked Enable-Protected);
 * not WAVE on the SAMD21 */
#define TCC_EP_CTRLA 0x0F007F60u

static int tcc_index(int pi) { return sam_periphs[pi].name[3] - '0'; }

static uint32_t tcc_reg(sam_mcu_t *m, int pi, uint32_t off) { return sam_rd32(m->regs[pi] + off); }

static int tcc_lupd(sam_mcu_t *m, int pi) { return (tcc_reg(m, pi, TCC_CTRLBSET_OFFSET) & TCC_CTRLBSET_LUPD) != 0; }

static void tcc_reset(sam_mcu_t *m, int pi)
{
    if (!m->pst[pi])
        m->pst[pi] = calloc(1, sizeof(tcc_t));
    tcc_t *s = m->pst[pi];
    memset(s, 0, sizeof *s);
    int k = tcc_index(pi);
    s->nch = k == 0 ? 4 : 2;
    s->gclk_id = k == 2 ? TCC2_GCLK_ID : TCC0_GCLK_ID;   /* TCC0 and TCC1 share one channel */
    s->max = k == 2 ? 0xFFFFu : 0xFFFFFFu;                /* TCC0, TCC1: 24 bits; TCC2: 16 (31.2 Overview) */
    s->per = s->perb = s->max;
    s->ready_per = SAM_NEVER;
    for (int c = 0; c < 4; c++)
        s->ready_cc[c] = SAM_NEVER;
    sam_slot_set(m, pi, SAM_NEVER);
}

/* ---------------------------------------------------------------- the counter's time line */

static uint64_t cycle_len(const tcc_t *s) { return ((uint64_t)s->top + 1u) * s->tick; }

/* the UPDATE at which a buffer ready at r is copied (with LUPD clear): the first wrap after both r and za */
static uint64_t apply_at(const tcc_t *s, uint64_t r)
{
    if (r == SAM_NEVER)
        return SAM_NEVER;
    uint64_t end = s->za + cycle_len(s);
    if (r < end)
        return end;
    uint64_t P = ((uint64_t)s->per + 1u) * s->tick;   /* regular cycles after the current one */
    return end + ((r - end) / P + 1u) * P;
}

/* the next time the counter's parameters change: a buffer copied, or the long cycle to MAX ending */
static uint64_t next_change(const tcc_t *s, int lupd)
{
    if (!s->running)
        return SAM_NEVER;
    uint64_t t = s->top != s->per ? s->za + cycle_len(s) : SAM_NEVER;
    if (lupd)
        return t;
    uint64_t a = apply_at(s, s->ready_per);
    if (a < t)
        t = a;
    for (int c = 0; c < s->nch; c++) {
        a = apply_at(s, s->ready_cc[c]);
        if (a < t)
            t = a;
    }
    return t;
}

/* the UPDATE at u (a change): a new cycle, the buffers ready before it copied */
static void update_at(tcc_t *s, uint64_t u, int lupd)
{
    s->za = u;
    if (!lupd) {
        if (s->ready_per < u) {
            s->per = s->perb;
            s->ready_per = SAM_NEVER;
        }
        for (int c = 0; c < s->nch; c++)
            if (s->ready_cc[c] < u) {
                s->cc[c] = s->ccb[c];
                s->ready_cc[c] = SAM_NEVER;
            }
    }
    s->top = s->per;
}

/* bring the counter to time t: every change up to t made, za the start of the cycle holding t. Returns the next
 * change after t, next_change's value then: moving za by whole periods (top = PER: no long cycle) leaves it, as a
 * buffer is taken over at the first wrap after its ready time and at or after za + one period, and the wrap found
 * before the move is past t, so at or after the new za + one period too. */
static uint64_t advance(tcc_t *s, int lupd, uint64_t t)
{
    if (!s->running || t < s->za)
        return next_change(s, lupd);
    uint64_t u;
    while ((u = next_change(s, lupd)) <= t)
        update_at(s, u, lupd);
    uint64_t P = cycle_len(s);
    if (s->top == s->per && t - s->za >= P)
        s->za += (t - s->za) / P * P;
    return u;
}

/* ---------------------------------------------------------------- the outputs */

/* high time of a cycle structure over [a, b): za's cycle to top, then cycles of PER + 1 counts; high while the count
 * is below cc. a >= za, or the cycles before za were the same as after (no change between a and za). */
static uint64_t high_const(const tcc_t *s, uint32_t cc, uint64_t a, uint64_t b)
{
    uint64_t hi = 0, z = s->za;
    if (b <= a)
        return 0;
    if (s->top != s->per) {   /* the long cycle to MAX first; a >= za then (PER was written at or after it began) */
        uint64_t e = z + cycle_len(s), h = z + ((uint64_t)(cc < s->top + 1u ? cc : s->top + 1u)) * s->tick;
        uint64_t x0 = a, x1 = b < h ? b : h;
        if (x1 > x0)
            hi += x1 - x0;
        if (b <= e)
            return hi;
        a = a > e ? a : e;
        z = e;
    }
    uint64_t P = ((uint64_t)s->per + 1u) * s->tick;
    uint64_t H = (uint64_t)(cc < s->per + 1u ? cc : s->per + 1u) * s->tick;
    if (a < z)
        z -= ((z - a) + P - 1u) / P * P;
    uint64_t fa = (a - z) / P * H + ((a - z) % P < H ? (a - z) % P : H);
    uint64_t fb = (b - z) / P * H + ((b - z) % P < H ? (b - z) % P : H);
    return hi + fb - fa;
}

/* Walk [t0, t1) of channel c through the changes in it (on a copy of the state): each stretch of constant
 * parameters is handed to `seg`. */
typedef void (*tcc_seg_fn)(const tcc_t *s, int c, uint64_t a, uint64_t b, void *ctx);

static void walk(const tcc_t *s0, int lupd, int c, uint64_t t0, uint64_t t1, tcc_seg_fn seg, void *ctx)
{
    tcc_t s = *s0;
    uint64_t a = t0 < s.t_start ? s.t_start : t0;
    /* before za nothing changed between a and za: the same cycles before it */
    uint64_t u = a < s.za ? next_change(&s, lupd) : advance(&s, lupd, a);
    while (a < t1) {
        uint64_t b = u < t1 ? u : t1;
        seg(&s, c, a, b, ctx);
        if (u >= t1)
            break;
        update_at(&s, u, lupd);
        a = u;
        u = next_change(&s, lupd);
    }
}

typedef struct {
    int waveform;
    uint64_t hi, den;
    double other;
} high_acc_t;

static void high_seg(const tcc_t *s, int c, uint64_t a, uint64_t b, void *ctx)
{
    high_acc_t *h = ctx;
    if (h->waveform) {   /* the waveform's own high time: exact in tu */
        h->hi += high_const(s, s->cc[c], a, b);
        return;
    }
    /* the mean of the waveform over whole periods: CC/(PER+1) of the time */
    uint64_t per = (uint64_t)s->per + 1u, d = s->cc[c] >= per ? per : s->cc[c];
    if (!h->den)
        h->den = per;
    if (per == h->den)
        h->hi += d * (b - a);
    else
        h->other += (double)d * (double)(b - a) / (double)per;
}

static tcc_t *tcc_state(sam_mcu_t *m, int tcc, int *pi)
{
    *pi = tcc >= 0 && tcc < 3 ? sam_idx.tcc[tcc] : -1;
    return *pi >= 0 ? m->pst[*pi] : NULL;
}

uint64_t sam_tcc_high(sam_mcu_t *m, int tcc, int wo, uint64_t t0, uint64_t t1, int waveform, uint64_t *top,
                      double *other)
{
    int pi;
    tcc_t *s = tcc_state(m, tcc, &pi);
    *top = 1;
    *other = 0.0;
    if (!s || !s->running || t1 <= t0)
        return 0;
    high_acc_t h = {waveform, 0, 0, 0.0};
    walk(s, tcc_lupd(m, pi), wo % s->nch, t0, t1, high_seg, &h);
    *other = h.other;
    *top = waveform ? 1u : h.den ? h.den : (uint64_t)s->per + 1u;
    return h.hi;
}

typedef struct {
    sam_tcc_piece_fn fn;
    void *ctx;
} piece_acc_t;

/* the output's constant pieces in one stretch: cycle by cycle */
static void piece_seg(const tcc_t *s, int c, uint64_t a, uint64_t b, void *ctx)
{
    piece_acc_t *p = ctx;
    uint64_t z = s->za, top = s->top;
    if (a < z) {
        uint64_t P = ((uint64_t)s->per + 1u) * s->tick;
        z -= ((z - a) + P - 1u) / P * P;
        top = s->per;
    }
    while (a < b) {
        uint64_t e = z + ((uint64_t)top + 1u) * s->tick;
        uint64_t h = z + (uint64_t)(s->cc[c] < top + 1u ? s->cc[c] : top + 1u) * s->tick;
        if (a < h) {
            uint64_t x = h < b ? h : b;
            p->fn(p->ctx, 1, x - a);
            a = x;
        }
        if (a < b && a < e) {
            uint64_t x = e < b ? e : b;
            p->fn(p->ctx, 0, x - a);
            a = x;
        }
        z = e;
        top = s->per;
    }
}

void sam_tcc_pieces(sam_mcu_t *m, int tcc, int wo, uint64_t t0, uint64_t t1, sam_tcc_piece_fn fn, void *ctx)
{
    int pi;
    tcc_t *s = tcc_state(m, tcc, &pi);
    if (t1 <= t0)
        return;
    if (!s || !s->running) {
        fn(ctx, 0, t1 - t0);
        return;
    }
    if (t0 < s->t_start) {
        uint64_t x = s->t_start < t1 ? s->t_start : t1;
        fn(ctx, 0, x - t0);
        t0 = x;
    }
    piece_acc_t p = {fn, ctx};
    walk(s, tcc_lupd(m, pi), wo % s->nch, t0, t1, piece_seg, &p);
}

uint64_t sam_tcc_period_held(sam_mcu_t *m, int tcc)
{
    int pi;
    tcc_t *s = tcc_state(m, tcc, &pi);
    if (!s || !s->running)
        return 1;
    return s->ready_per != SAM_NEVER ? 0 : (uint64_t)s->per + 1u;
}

int sam_tcc_state(sam_mcu_t *m, int tcc, uint64_t t, sam_tcc_info_t *out)
{
    int pi;
    tcc_t *s = tcc_state(m, tcc, &pi);
    memset(out, 0, sizeof *out);
    if (!s)
        return -1;
    tcc_t st = *s;   /* a copy: the state moves on only where the plant has integrated up to */
    advance(&st, tcc_lupd(m, pi), t);
    s = &st;
    out->running = s->running;
    out->prescaler = (uint32_t)TCC_PRESC[(tcc_reg(m, pi, TCC_CTRLA_OFFSET) >> TCC_CTRLA_PRESCALER_Pos) & 7u];
    out->per = s->per;
    out->top = s->top;
    out->tick_tu = s->tick;
    out->period_tu = s->running ? ((uint64_t)s->per + 1u) * s->tick : 0;
    out->cycle_start_tu = s->za;
    for (int c = 0; c < 4; c++)
        out->cc[c] = s->cc[c];
    return 0;
}

/* ---------------------------------------------------------------- registers */

#define TCC_CTRLBCLR_OFFSET 0x04   /* CTRLBCLR, beside CTRLBSET (0x05): the same bits */

/* COUNT is read-synchronised on demand (DS40001882 31.6.6 Synchronization; 31.8.3 CTRLBSET.CMD = READSYNC): the
 * command, carried out once its write has synchronised (SYNCBUSY.CTRLB, CMD reading back non-zero until then), brings
 * the counter's value over; COUNT reads it until the next command (before any, its reset value 0). PER and CCx are
 * not read-synchronised on the SAMD21 (31.6.6 lists only CTRLB and COUNT) and read as they are. Called
 * first by every access and event, before the counter's state moves past rs_at, so the value is the one it had then. */
static void tcc_settle(sam_mcu_t *m, int pi)
{
    tcc_t *s = m->pst[pi];
    if (!s->rs_pending || sam_now(m) < s->rs_at)
        return;
    tcc_t st = *s;
    advance(&st, tcc_lupd(m, pi), s->rs_at);
    s->rs_count = st.running && s->rs_at >= st.za ? (uint32_t)((s->rs_at - st.za) / st.tick) : 0;
    s->rs_pending = 0;
}

static void tcc_sync(sam_mcu_t *m, int pi, uint32_t bits)
{
    tcc_t *s = m->pst[pi];
    uint64_t hz = sam_gclk_hz(m, s->gclk_id), now = sam_now(m);
    if (now < s->sync_until && (s->sync_bits & bits)) {
        if (s->sync_until == SAM_NEVER) {
            sam_fail(m, "write to a TCC register synchronising without a clock: the bus would stall forever");
            return;
        }
        m->t += s->sync_until - now;
        now = s->sync_until;
        tcc_settle(m, pi);   /* a READSYNC the stall waited for was carried out first */
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

/* before anything is looked at or changed: the plant integrates the outputs up to now if the counter's parameters
 * changed since (a buffer copied at an UPDATE, which is no event), then the state moves to now */
static void tcc_catch_up(sam_mcu_t *m, int pi, int always)
{
    tcc_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    int lupd = tcc_lupd(m, pi);
    if (always || next_change(s, lupd) <= now)
        sam_world_tcc_will_change(m, tcc_index(pi));
    advance(s, lupd, now);
}

static int tcc_read(sam_mcu_t *m, int pi, int ri, uint32_t *v)
{
    tcc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    uint64_t now = sam_now(m);
    tcc_settle(m, pi);
    tcc_catch_up(m, pi, 0);
    int pending = next_change(s, tcc_lupd(m, pi)) != SAM_NEVER;
    if (off == TCC_SYNCBUSY_OFFSET) {
        *v = now < s->sync_until ? s->sync_bits : 0;
        return SAM_DONE;
    }
    /* STATUS.PERBV, CCBVn and PER, CCn change at the UPDATE that takes a buffered value over, which is no event: while
     * one is pending, a read of them is activity, so a loop() polling them is never fast-forwarded past the change
     * (sam_ff.c) */
    if (off == TCC_STATUS_OFFSET) {
        uint32_t st = s->running ? 0 : TCC_STATUS_STOP;
        if (s->ready_per != SAM_NEVER)
            st |= TCC_STATUS_PERBV;
        for (int c = 0; c < s->nch; c++)
            if (s->ready_cc[c] != SAM_NEVER)
                st |= TCC_STATUS_CCBV0 << c;
        if (pending)
            sam_activity(m);
        *v = st;
        return SAM_DONE;
    }
    if (off >= TCC_CC_OFFSET && off < TCC_CC_OFFSET + 16) {
        *v = s->cc[(off - TCC_CC_OFFSET) / 4];
        if (pending)
            sam_activity(m);
        return SAM_DONE;
    }
    if (off >= TCC_CCB_OFFSET && off < TCC_CCB_OFFSET + 16) {
        *v = s->ccb[(off - TCC_CCB_OFFSET) / 4];
        return SAM_DONE;
    }
    if (off == TCC_PER_OFFSET || off == TCC_PERB_OFFSET) {
        *v = off == TCC_PER_OFFSET ? s->per : s->perb;
        if (pending)
            sam_activity(m);
        return SAM_DONE;
    }
    if (off == TCC_COUNT_OFFSET) {
        /* the last read synchronisation's value (tcc_settle): a constant until the next READSYNC, a write that is
         * itself activity, so the read is not (the TCC has no continuous read synchronisation) */
        *v = s->rs_count;
        return SAM_DONE;
    }
    if ((off == TCC_CTRLBSET_OFFSET || off == TCC_CTRLBCLR_OFFSET) && s->rs_pending) {
        *v = (tcc_reg(m, pi, TCC_CTRLBSET_OFFSET) & 0xFFu) | TCC_CTRLBSET_CMD_READSYNC;   /* not yet carried out */
        return SAM_DONE;
    }
    if (off == TCC_INTFLAG_OFFSET)
        return SAM_UNCOVERED;   /* the overflow and match flags are not tracked (no TCC interrupt is modelled) */
    return SAM_GENERIC;
}

/* PER written while counting takes effect at once: below the count, the counter runs on to MAX before it wraps */
static void tcc_set_per(sam_mcu_t *m, tcc_t *s, uint32_t per)
{
    uint64_t now = sam_now(m);
    s->per = s->perb = per;
    s->ready_per = SAM_NEVER;
    if (s->running && now >= s->za) {
        uint64_t count = (now - s->za) / s->tick;
        s->top = count > per ? s->max : per;
    } else {
        s->top = per;
    }
}

static int tcc_write(sam_mcu_t *m, int pi, int ri, uint32_t v, uint32_t mask)
{
    tcc_t *s = m->pst[pi];
    uint32_t off = sam_regs[ri].offset;
    v &= mask;
    tcc_settle(m, pi);
    tcc_catch_up(m, pi, 1);   /* the motors integrate up to now with the old parameters */
    if (off == TCC_CTRLA_OFFSET) {
        if (v & TCC_CTRLA_SWRST) {
            memset(m->regs[pi], 0, sam_periphs[pi].size);
            for (unsigned r = sam_periphs[pi].reg0; r < sam_periphs[pi].reg1; r++)
                if (sam_regs[r].kind == SAM_KIND_PLAIN)
                    sam_reg_put(m, (int)r, sam_regs[r].reset);
            tcc_reset(m, pi);
            tcc_sync(m, pi, TCC_SYNCBUSY_SWRST);
            tcc_schedule(m, pi);
            sam_activity(m);
            return SAM_DONE;
        }
        uint32_t old = tcc_reg(m, pi, TCC_CTRLA_OFFSET);
        v = sam_enable_protected(m, ri, v, mask, TCC_EP_CTRLA, (old & TCC_CTRLA_ENABLE) != 0);
        if (v & (0xFu << 24)) {
            sam_fail(m, "%s capture channels (CTRLA.CPTEN) are not modelled", sam_periphs[pi].name);
            return SAM_DONE;
        }
        tcc_sync(m, pi, TCC_SYNCBUSY_ENABLE);
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
        tcc_sync(m, pi, TCC_SYNCBUSY_WAVE);
        return SAM_GENERIC;
    }
    if (off == TCC_PER_OFFSET) {
        tcc_sync(m, pi, TCC_SYNCBUSY_PER);
        tcc_set_per(m, s, v & s->max);
        sam_generic_write(m, ri, v, mask);
        sam_activity(m);
        return SAM_DONE;
    }
    if (off == TCC_PERB_OFFSET) {
        /* buffered: copied to PER at the first UPDATE after the write has synchronised (not while LUPD is set) */
        tcc_sync(m, pi, TCC_SYNCBUSY_PERB);
        s->perb = v & s->max;
        s->ready_per = s->sync_until;
        sam_generic_write(m, ri, v, mask);
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off >= TCC_CC_OFFSET && off < TCC_CC_OFFSET + 16) {
        int c = (int)(off - TCC_CC_OFFSET) / 4;
        tcc_sync(m, pi, TCC_SYNCBUSY_CC0 << c);
        s->cc[c] = v & s->max;
        s->ccb[c] = s->cc[c];
        s->ready_cc[c] = SAM_NEVER;
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off >= TCC_CCB_OFFSET && off < TCC_CCB_OFFSET + 16) {
        int c = (int)(off - TCC_CCB_OFFSET) / 4;
        tcc_sync(m, pi, TCC_SYNCBUSY_CCB0 << c);
        s->ccb[c] = v & s->max;
        s->ready_cc[c] = s->sync_until;   /* valid (STATUS.CCBVn) until copied at an UPDATE */
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off == TCC_CTRLBSET_OFFSET && (v & TCC_CTRLBSET_CMD_Msk) == TCC_CTRLBSET_CMD_READSYNC &&
        !(v & ~(TCC_CTRLBSET_CMD_Msk | TCC_CTRLBSET_LUPD))) {
        tcc_sync(m, pi, TCC_SYNCBUSY_CTRLB);   /* tcc_settle: COUNT brought over once this has synchronised */
        s->rs_pending = 1;
        s->rs_at = s->sync_until;
        if (v & TCC_CTRLBSET_LUPD)
            sam_generic_write(m, ri, TCC_CTRLBSET_LUPD, mask);
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    if (off == TCC_CTRLBCLR_OFFSET && (v & TCC_CTRLBSET_LUPD)) {
        /* 31.6.2.6 Double Buffering: with LUPD cleared, the buffers still valid are copied at the next UPDATE */
        sam_generic_write(m, ri, v, mask);
        sam_activity(m);
        tcc_schedule(m, pi);
        return SAM_DONE;
    }
    int protect = off == TCC_WEXCTRL_OFFSET || off == TCC_DRVCTRL_OFFSET || off == TCC_EVCTRL_OFFSET ||
                  off == TCC_FCTRLA_OFFSET || off == TCC_FCTRLB_OFFSET;
    if (protect)
        v = sam_enable_protected(m, ri, v, mask, 0xFFFFFFFFu,
                                 (tcc_reg(m, pi, TCC_CTRLA_OFFSET) & TCC_CTRLA_ENABLE) != 0);
    if ((off == TCC_CTRLBSET_OFFSET && (v & ~TCC_CTRLBSET_LUPD)) ||
        ((off == TCC_WEXCTRL_OFFSET || off == TCC_DRVCTRL_OFFSET || off == TCC_EVCTRL_OFFSET ||
          off == TCC_FCTRLA_OFFSET || off == TCC_FCTRLB_OFFSET || off == TCC_PATT_OFFSET ||
          off == TCC_INTENSET_OFFSET) &&
         v)) {
        sam_fail(m, "%s = 0x%x: not modelled (only normal PWM with buffered compare values)", sam_regs[ri].name, v);
        return SAM_DONE;
    }
    if (protect) {
        sam_generic_write(m, ri, v, mask);   /* the value as protection left it */
        return SAM_DONE;
    }
    return SAM_GENERIC;
}

static void tcc_fire(sam_mcu_t *m, int pi)
{
    tcc_t *s = m->pst[pi];
    uint64_t now = sam_now(m);
    tcc_settle(m, pi);
    if (s->pending_enable && now >= s->sync_until) {
        uint32_t presc = (uint32_t)TCC_PRESC[(tcc_reg(m, pi, TCC_CTRLA_OFFSET) >> TCC_CTRLA_PRESCALER_Pos) & 7u];
        sam_world_tcc_will_change(m, tcc_index(pi));
        s->pending_enable = 0;
        s->tick = sam_tu_per_tick(m, sam_gclk_hz(m, s->gclk_id), presc, sam_periphs[pi].name);
        if (s->tick) {   /* the counter starts from 0 now (31.6.2.1: COUNT is 0 after the reset the firmware does) */
            s->running = 1;
            s->t_start = s->za = now;
            s->top = s->per;
        }
    }
    tcc_schedule(m, pi);
}

const sam_model_t sam_model_tcc = {"Tcc", tcc_reset, NULL, tcc_read, tcc_write, tcc_fire};
