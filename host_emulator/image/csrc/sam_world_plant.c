/* The world's plant side: pin edges into the boards, the drivers and motors from the boards' pins, plant windows. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "sam_world.h"
#include "he_step.h"

/* ---------------------------------------------------------------- pin events */

int sam_world_pinq_push(sam_world_t *w, int mcu, uint64_t t, int pin, int level)
{
    sam_pinq_t *q = &w->pinq[mcu];
    if (q->n >= SAM_PINQ)
        return -1;
    unsigned i = q->n++;
    /* insertion from the tail: events come nearly in order */
    while (i > 0) {
        sam_pinev_t *prev = &q->ev[(q->head + i - 1) % SAM_PINQ];
        if (prev->t <= t)
            break;
        q->ev[(q->head + i) % SAM_PINQ] = *prev;
        i--;
    }
    sam_pinev_t *e = &q->ev[(q->head + i) % SAM_PINQ];
    e->t = t;
    e->pin = (int8_t)pin;
    e->level = (int8_t)level;
    sam_mcu_t *m = w->mcu[mcu];
    sam_slot_set(m, q->slot, q->ev[q->head].t);
    return 0;
}

/* the pins' event source: the edges due now */
static void pin_fire(sam_mcu_t *m, void *ctx)
{
    (void)ctx;
    sam_world_t *w = m->w;
    sam_pinq_t *q = &w->pinq[m->id];
    uint64_t now = sam_now(m);
    while (q->n && q->ev[q->head].t <= now) {
        sam_pinev_t e = q->ev[q->head];
        q->head = (q->head + 1) % SAM_PINQ;
        q->n--;
        if (!m->halted)
            sam_pin_drive(m, e.pin, e.level);
    }
    sam_slot_set(m, q->slot, q->n ? q->ev[q->head].t : SAM_NEVER);
}

/* ---------------------------------------------------------------- drivers and motors */

/* level a DRV8874 input sees: the board's GPIO output, its pull-up, else the driver's own pull-down */
static int driver_input(sam_mcu_t *m, int pin)
{
    if (m->halted)
        return 0;
    int driven;
    int o = sam_pin_out(m, pin, &driven);
    return o == 1;
}

/* what function f of a pin is, for the drivers: (tcc << 8) | wo of a TCC waveform output, -1 another peripheral's
 * signal (it drives nothing here) or a letter the pin does not have; from the generated pin table, once */
static int16_t pin_tcc[64][8];

void sam_world_plant_init(void)
{
    static int done;
    if (done)
        return;
    for (int pin = 0; pin < 64; pin++)
        for (int f = 0; f < 8; f++)
            pin_tcc[pin][f] = -1;
    for (unsigned k = 0; k < sam_npinmux; k++) {
        const sam_pinmux_t *p = &sam_pinmux[k];
        int pin = p->pin, f = p->func;
        if (pin >= 0 && pin < 64 && f >= 0 && f < 8 && !strncmp(p->periph, "TCC", 3) && !strncmp(p->signal, "WO", 2))
            pin_tcc[pin][f] = (int16_t)(((p->periph[3] - '0') << 8) | atoi(p->signal + 2));
    }
    done = 1;
}

/* high time of an EN input over [t0, t1): a TCC waveform output through the pin mux (the mean path: numerator in tu,
 * *den its period in counts, *other a part after a period change; the waveform path: tu, *den = 1), or a GPIO
 * level (*den = 1) */
static uint64_t enable_high(sam_mcu_t *m, int pin, uint64_t t0, uint64_t t1, uint64_t *den, double *other)
{
    *den = 1;
    *other = 0.0;
    if (m->halted)
        return 0;
    int f = sam_pin_function(m, pin);
    if (f < 0)
        return driver_input(m, pin) ? t1 - t0 : 0;
    int tw = pin_tcc[pin][f];
    return tw < 0 ? 0 : sam_tcc_high(m, tw >> 8, tw & 0xFF, t0, t1, m->w->cfg.pwm_waveform != 0, den, other);
}

/* ---- the motors' electrical model (cfg.motor_tau_s > 0): L di/dt = V(t) - R i - e, in j = R i (volts) ----
 * tau dj/dt = V - e - j over each piece of constant terminal voltage V (the supply with PH's sign while EN is high,
 * 0 while it is low: the DRV8874 brakes, low-side slow decay; asleep: outputs off, the current gone). */
static void current_follow(sam_world_t *w, sam_motor_t *mo, double e)
{
    double tau = w->cfg.motor_tau_s * (double)SAM_TU_HZ;   /* tu */
    for (int k = 0; k < mo->npiece; k++) {
        double d = (double)mo->piece[k].dt;
        if (mo->piece[k].v == SAM_MOTOR_OFF) {
            mo->j = 0.0;
            continue;
        }
        double vinf = (double)mo->piece[k].v * w->cfg.supply_v - e, x = d / tau;
        mo->jint += vinf * d - (mo->j - vinf) * tau * expm1(-x);
        mo->j = vinf + (mo->j - vinf) * exp(-x);
    }
    mo->npiece = 0;
}

typedef struct {
    sam_world_t *w;
    sam_motor_t *mo;
    double e;
    int sign;
} piece_ctx_t;

static void piece_add(piece_ctx_t *c, int v, uint64_t dt)
{
    sam_motor_t *mo = c->mo;
    if (!dt)
        return;
    if (mo->npiece && mo->piece[mo->npiece - 1].v == v) {
        mo->piece[mo->npiece - 1].dt += dt;
        return;
    }
    if (mo->npiece == SAM_MOTOR_PIECES)   /* more edges in a window than it holds: the current follows them now */
        current_follow(c->w, mo, c->e);
    mo->piece[mo->npiece].v = (int8_t)v;
    mo->piece[mo->npiece].dt = dt;
    mo->npiece++;
}

static void piece_level(void *ctx, int level, uint64_t dt)
{
    piece_ctx_t *c = ctx;
    piece_add(c, level ? c->sign : 0, dt);
}

/* the back-EMF of motor (j, ch) over this window: the plant's speed at the window's start over S_L */
static double back_emf(sam_world_t *w, int j, int ch)
{
    return w->cfg.v[ch * w->cfg.ncells + j] / w->cfg.plant->speed_const;
}

static void motor_pieces(sam_world_t *w, int j, int ch, int awake, int ph, uint64_t t0, uint64_t t1)
{
    sam_mcu_t *m = w->mcu[w->cell_mcu[j]];
    piece_ctx_t c = {w, &w->motor[j][ch], back_emf(w, j, ch), ph ? 1 : -1};
    int pin = w->cfg.pin_en[ch], f = m->halted ? -1 : sam_pin_function(m, pin);
    if (!awake)
        piece_add(&c, SAM_MOTOR_OFF, t1 - t0);
    else if (m->halted || (f >= 0 && pin_tcc[pin][f] < 0))
        piece_add(&c, 0, t1 - t0);
    else if (f < 0)
        piece_add(&c, driver_input(m, pin) ? c.sign : 0, t1 - t0);
    else
        sam_tcc_pieces(m, pin_tcc[pin][f] >> 8, pin_tcc[pin][f] & 0xFF, t0, t1, piece_level, &c);
}

static void motor_integrate(sam_world_t *w, int j, uint64_t t)
{
    int mi = w->cell_mcu[j];
    if (mi < 0)
        return;
    sam_mcu_t *m = w->mcu[mi];
    int awake = driver_input(m, w->cfg.pin_nsleep);
    for (int ch = 0; ch < 2; ch++) {
        sam_motor_t *mo = &w->motor[j][ch];
        if (t <= mo->t_last)
            continue;
        int ph = driver_input(m, w->cfg.pin_ph[ch]);
        if (w->cfg.motor_tau_s > 0.0)
            motor_pieces(w, j, ch, awake, ph, mo->t_last, t);
        if (awake) {
            double other;
            uint64_t den, hi = enable_high(m, w->cfg.pin_en[ch], mo->t_last, t, &den, &other);
            if (!mo->den)
                mo->den = den;
            if (mo->den == 1 && den > 1) {   /* GPIO time so far, in the PWM's units from now on */
                mo->hi *= (int64_t)den;
                mo->den = den;
            }
            if (den == mo->den)
                mo->hi += ph ? (int64_t)hi : -(int64_t)hi;
            else if (den == 1 && mo->den > 1)
                mo->hi += (ph ? 1 : -1) * (int64_t)(hi * mo->den);
            else
                mo->hi_other += (ph ? 1.0 : -1.0) * (double)hi / (double)den;
            if (other != 0.0)   /* a period change inside the stretch (mean-duty path) */
                mo->hi_other += (ph ? 1.0 : -1.0) * other;
            mo->awake_tu += t - mo->t_last;
        }
        mo->t_last = t;
    }
}

void sam_world_pins_will_change(sam_mcu_t *m)
{
    if (m->role == SAM_ROLE_CELL && m->cell >= 0)
        motor_integrate(m->w, m->cell, sam_now(m));
}

/* Whether motor_integrate(w, j, now) may be left to the cell's next integration at t (a pin change, a TCC write or
 * catch-up, the window's end) when no pin, mux or TCC register changes in between: the sums over [t_last, now) and
 * [now, t) then add up to the sum over [t_last, t) bit for bit, checked path by path:
 * - awake_tu, t_last: integers, additive; PH and NSLEEP (GPIO levels) and `halted` hold (a halt integrates first).
 * - EN as GPIO, a function other than a TCC output, a stopped TCC (it starts at an event that integrates first), a
 *   halted board: enable_high's numerator is a whole number of tu with den 1, added to mo->hi (times mo->den when
 *   that is a PWM period): integer arithmetic, additive.
 * - the waveform path (cfg.pwm_waveform): the waveform's exact high time in tu, den 1, other 0: additive (the
 *   measure of the set of high instants; walk's copy of the counter cuts it at the same changes either way).
 * - the mean path: each stretch of constant PER adds CC * dt to the integer numerator when its period is the first
 *   stretch's (den) and that is mo->den, otherwise (double) numerator / den to hi_other, or `other`, in double:
 *   rounded, so not additive. It is exact when the period cannot change over [t_last, t) and mo->den is 0, 1 or
 *   that period: PER changes by a write (integrates first) or by a buffered PERB taken over at an UPDATE, which is
 *   no event, so only while no PERB is pending (sam_tcc_period_held; a pending one is seen in the counter's state
 *   until an integration's catch-up takes it over). CC changes inside it stay in the integer numerator.
 * - the electrical model (cfg.motor_tau_s > 0): its pieces merge to the same runs of constant voltage either way,
 *   but a full piece table is followed with the back-EMF of w->cfg.v read then, which Python may set between two
 *   runs: not proven here, so it integrates now. */
static int split_exact(sam_world_t *w, int j)
{
    int mi = w->cell_mcu[j];
    if (mi < 0)
        return 1;   /* motor_integrate does nothing */
    if (w->cfg.motor_tau_s > 0.0)
        return 0;
    sam_mcu_t *m = w->mcu[mi];
    if (w->cfg.pwm_waveform || m->halted)
        return 1;
    for (int ch = 0; ch < 2; ch++) {
        int pin = w->cfg.pin_en[ch], f = sam_pin_function(m, pin);
        if (f < 0 || pin_tcc[pin][f] < 0)
            continue;
        uint64_t per = sam_tcc_period_held(m, pin_tcc[pin][f] >> 8), den = w->motor[j][ch].den;
        if (!per || (per > 1 && den > 1 && den != per))   /* per 1: den 1, the integer path */
            return 0;
    }
    return 1;
}

void sam_world_pins_unchanged(sam_mcu_t *m)
{
    if (m->role == SAM_ROLE_CELL && m->cell >= 0 && !split_exact(m->w, m->cell))
        motor_integrate(m->w, m->cell, sam_now(m));
}

void sam_world_pins_changed(sam_mcu_t *m) { sam_bus_lines_changed(m); }

void sam_world_tcc_will_change(sam_mcu_t *m, int tcc)
{
    (void)tcc;
    sam_world_pins_will_change(m);
}

/* ---------------------------------------------------------------- plant windows */

int sam_world_window(sam_world_t *w, uint64_t t0)
{
    uint64_t t1 = t0 + w->window_tu;
    he_plant_t *p = w->cfg.plant;
    int n = w->cfg.ncells;
    double W = (double)w->window_tu / (double)SAM_TU_HZ;
    /* the window that just ended: each motor's means */
    for (int j = 0; j < n; j++) {
        motor_integrate(w, j, t0);
        for (int ch = 0; ch < 2; ch++) {
            sam_motor_t *mo = &w->motor[j][ch];
            double hi = (double)mo->hi / (double)(mo->den ? mo->den : 1) + mo->hi_other;   /* tu */
            mo->volt = mo->awake_tu ? w->cfg.supply_v * hi / (double)mo->awake_tu : 0.0;
            if (w->cfg.motor_tau_s > 0.0) {   /* R times the mean current over the time awake, plus the back-EMF */
                double e = back_emf(w, j, ch);
                current_follow(w, mo, e);
                mo->volt = mo->awake_tu ? mo->jint / (double)mo->awake_tu + e : 0.0;
                mo->jint = 0.0;
            }
            mo->awake = (double)mo->awake_tu / (double)w->window_tu;
            mo->hi = 0;
            mo->den = 0;
            mo->hi_other = 0.0;
            mo->awake_tu = 0;
            /* the plant's motor term m (V - omega/S_L) with m = Kt * awake fraction: torque Kt (Vmean - a omega/S_L) */
            p->mgain[ch][j] = w->cfg.kt * mo->awake;
            p->volt[ch][j] = mo->volt;
        }
    }
    if (w->plant_start == SAM_NEVER || t0 < w->plant_start)
        return 0;
    memcpy(w->xprev, w->cfg.x, sizeof(double) * 2 * (size_t)n);
    double h = W / w->cfg.substeps;
    int rc = he_advance(p, w->cfg.stepper, h, w->cfg.substeps, &w->plant_t, w->cfg.x, w->cfg.v);
    if (rc != HE_OK)
        return sam_world_fail(w, "plant: error %d (%s) at t = %.6f s (plant time %.6f s): numerically unstable or out of its "
                    "physical range", rc, rc == HE_ERR_BAND ? "a band stretched past its fit's range" : "state",
                    (double)t0 / (double)SAM_TU_HZ, w->plant_t);
    /* encoder edges inside the window */
    double cpr = w->cfg.counts_per_rad;
    for (int j = 0; j < n; j++) {
        int mi = w->cell_mcu[j];
        if (mi < 0)
            continue;
        for (int ch = 0; ch < 2; ch++) {
            int i = ch * n + j;
            double c0 = w->xprev[i] * cpr, c1 = w->cfg.x[i] * cpr;
            double cf = floor(c1);
            if (cf > 2.0e9 || cf < -2.0e9)
                return sam_world_fail(w, "encoder %d of cell %d beyond 2e9 counts", ch, j + 1);
            int32_t target = (int32_t)cf, cur = w->count[j][ch];
            while (cur != target) {
                int32_t next = cur + (target > cur ? 1 : -1);
                double boundary = target > cur ? (double)next : (double)cur;
                double frac = c1 != c0 ? (boundary - c0) / (c1 - c0) : 1.0;
                frac = frac < 0.0 ? 0.0 : frac > 1.0 ? 1.0 : frac;
                uint64_t te = t0 + (uint64_t)(frac * (double)w->window_tu);
                int g0 = he_gray(cur), g1 = he_gray(next), diff = g0 ^ g1;
                int chan = diff & 2 ? 0 : 1;   /* A is bit 1, B bit 0 */
                int level = chan == 0 ? (g1 >> 1) & 1 : g1 & 1;
                if (sam_world_pinq_push(w, mi, te, w->cfg.pin_enc[ch][chan], level))
                    return sam_world_fail(w, "cell %d: more than %d encoder edges pending (the plant moved too fast for the "
                                "window)", j + 1, SAM_PINQ);
                cur = next;
            }
            w->count[j][ch] = cur;
        }
    }
    (void)t1;
    return 0;
}

/* The pins' event source on a board (registered when the world loads it). */
void sam_world_pins_init(sam_mcu_t *m)
{
    m->w->pinq[m->id].slot = sam_source_add(m, pin_fire, NULL, NULL, SAM_SRC_UNPOWERED);
}

int sam_world_tcc_info(const sam_world_t *w, int mcu, int tcc, sam_tcc_info_t *out)
{
    if (mcu < 0 || mcu >= w->nmcu || !w->mcu[mcu])
        return -1;
    const sam_mcu_t *m = w->mcu[mcu];   /* the board's time, as sam_harness_now gives it */
    return sam_tcc_state(w->mcu[mcu], tcc, m->ff.parked && m->t < w->t ? w->t : m->t, out);
}

/* A board's TCC output high time over [t0, t1) on either path (sam_tcc_high); 0 for no such board. */
static uint64_t tcc_figure(const sam_world_t *w, int mcu, int tcc, int wo, uint64_t t0, uint64_t t1, int waveform,
                           uint64_t *den, double *other)
{
    *den = 1;
    *other = 0.0;
    if (mcu < 0 || mcu >= w->nmcu || !w->mcu[mcu])
        return 0;
    return sam_tcc_high(w->mcu[mcu], tcc, wo, t0, t1, waveform, den, other);
}

uint64_t sam_world_tcc_high(const sam_world_t *w, int mcu, int tcc, int wo, uint64_t t0, uint64_t t1)
{
    uint64_t den;
    double other;
    return tcc_figure(w, mcu, tcc, wo, t0, t1, 1, &den, &other);
}

uint64_t sam_world_tcc_mean(const sam_world_t *w, int mcu, int tcc, int wo, uint64_t t0, uint64_t t1, uint64_t *den,
                            double *other)
{
    return tcc_figure(w, mcu, tcc, wo, t0, t1, 0, den, other);
}
