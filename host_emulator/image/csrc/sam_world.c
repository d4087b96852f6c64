/* The image tier's world: boards on a plant (drivers, motors, encoders), lock-step time, faults, and the Python API. */
#define _POSIX_C_SOURCE 200809L   /* pthreads, sched_yield */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <pthread.h>
#include <sched.h>
#include "sam_world.h"
#include "sam_vendor_gen.h"
#include "he_step.h"

int he_gray(int32_t count);   /* he_hil.c: (A << 1) | B of an encoder count, the hil tier's own encoder */

/*
 * Time loop (sam_world_run). The plant advances in windows of W: at the start of each window it steps over it
 * with each motor's mean voltage and awake fraction of the window before (a lag of one window) and turns the
 * encoders' count changes into pin edges at the times linear interpolation of the angle gives, inside the window.
 *
 * The boards then run the window apart in time, each as far as nothing another board does can still reach it
 * (conservative parallel simulation). Boards affect each other only through bus steps that take effect at least
 * T_MIN (the shortest SCL period, sam_i2c.c) after their cause, and a board that sends a step stops T_MIN after
 * the step takes effect (the receiver may answer then). The primary runs as far as the cells let it (a cell that
 * holds SCL may answer any time from T_MIN on; one with a step to take may answer it); each cell then runs as far
 * as the primary lets it: T_MIN past the primary, or to the window's end while the primary sees SCL held and has
 * no release to take. So no step ever reaches a board that has run past it (checked), and results do not depend
 * on how far boards run at a time (round_s), nor on fast-forwarding, nor on the order cells run in.
 * World-level faults start and end at round boundaries placed at their times.
 */

static int pool_start(sam_world_t *w, int nthreads);
static void pool_stop(sam_world_t *w);

static uint64_t tu_of(double s) { return (uint64_t)llround(s * (double)SAM_TU_HZ); }

/* Append a line to a notes buffer of capacity cap; when full, the oldest lines go (whole lines). */
static void notes_append(char *buf, uint32_t *len, uint32_t cap, const char *line, uint32_t n)
{
    if (*len + n > cap) {
        uint32_t drop = *len / 2;
        while (drop < *len && buf[drop - 1] != '\n')
            drop++;
        memmove(buf, buf + drop, *len - drop);
        *len -= drop;
    }
    if (*len + n <= cap) {
        memcpy(buf + *len, line, n);
        *len += n;
    }
}

static uint32_t vformat(char line[400], const char *fmt, va_list ap)
{
    int n = vsnprintf(line, 399, fmt, ap);
    if (n < 0)
        return 0;
    if (n > 398)
        n = 398;
    line[n++] = '\n';
    return (uint32_t)n;
}

/* A note from the world itself (run between boards' runs). */
void sam_world_note(sam_world_t *w, const char *fmt, ...)
{
    char line[400];
    va_list ap;
    va_start(ap, fmt);
    uint32_t n = vformat(line, fmt, ap);
    va_end(ap);
    notes_append(w->notes, &w->notes_len, sizeof w->notes, line, n);
}

/* A note from a board: kept with the board until the world collects the boards' notes in board order (boards
 * may run at the same time on several threads). */
void sam_note(sam_mcu_t *m, const char *fmt, ...)
{
    char line[400];
    va_list ap;
    va_start(ap, fmt);
    uint32_t n = vformat(line, fmt, ap);
    va_end(ap);
    notes_append(m->notes, &m->notes_len, SAM_BOARD_NOTES, line, n);
}

static void collect_notes(sam_world_t *w)
{
    for (int i = 0; i < w->nmcu; i++) {
        sam_mcu_t *m = w->mcu[i];
        if (m && m->notes_len) {
            notes_append(w->notes, &w->notes_len, sizeof w->notes, m->notes, m->notes_len);
            m->notes_len = 0;
        }
    }
}

uint32_t sam_world_notes(sam_world_t *w, char *buf, uint32_t cap)
{
    collect_notes(w);
    uint32_t n = w->notes_len < cap ? w->notes_len : cap;
    memcpy(buf, w->notes, n);
    memmove(w->notes, w->notes + n, w->notes_len - n);
    w->notes_len -= n;
    return n;
}

static int fail(sam_world_t *w, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w->err, sizeof w->err, fmt, ap);
    va_end(ap);
    return -1;
}

const char *sam_world_error(const sam_world_t *w) { return w->err; }

void sam_world_set_trace(sam_world_t *w, int32_t trace, int32_t boards)
{
    w->cfg.trace = trace;
    w->cfg.trace_boards = boards;
}
uint64_t sam_world_time(const sam_world_t *w) { return w->t; }
uint64_t sam_tu_hz(void) { return SAM_TU_HZ; }
uint32_t sam_world_nregs(void) { return sam_nregs; }
const char *sam_world_reg_name(uint32_t ri) { return sam_reg_name((int)ri); }

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
    sam_slot_set(m, SAM_SLOT_PINS, q->ev[q->head].t);
    return 0;
}

void sam_world_pin_event(sam_mcu_t *m)
{
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
    sam_slot_set(m, SAM_SLOT_PINS, q->n ? q->ev[q->head].t : SAM_NEVER);
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

/* high time of an EN input over [t0, t1): a TCC waveform output through the pin mux (numerator in tu, *den its
 * period in counts), or a GPIO level (*den = 1) */
/* what function f of a pin is, for the drivers: (tcc << 8) | wo of a TCC waveform output, -1 another peripheral's
 * signal (it drives nothing here) or a letter the pin does not have; from the generated pin table, once */
static int16_t pin_tcc[64][8];

static void pin_tcc_table(void)
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

static uint64_t enable_high(sam_mcu_t *m, int pin, uint64_t t0, uint64_t t1, uint64_t *den)
{
    *den = 1;
    if (m->halted)
        return 0;
    int f = sam_pin_function(m, pin);
    if (f < 0)
        return driver_input(m, pin) ? t1 - t0 : 0;
    int tw = pin_tcc[pin][f];
    return tw < 0 ? 0 : sam_tcc_high(m, tw >> 8, tw & 0xFF, t0, t1, den);
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
        if (awake) {
            int ph = driver_input(m, w->cfg.pin_ph[ch]);
            uint64_t den, hi = enable_high(m, w->cfg.pin_en[ch], mo->t_last, t, &den);
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

void sam_world_pins_changed(sam_mcu_t *m) { sam_bus_lines_changed(m); }

void sam_world_tcc_will_change(sam_mcu_t *m, int tcc)
{
    (void)tcc;
    sam_world_pins_will_change(m);
}

/* ---------------------------------------------------------------- plant windows */

static int window(sam_world_t *w, uint64_t t0)
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
        return fail(w, "plant: error %d (%s) at t = %.6f s (plant time %.6f s): numerically unstable or out of its "
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
                return fail(w, "encoder %d of cell %d beyond 2e9 counts", ch, j + 1);
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
                    return fail(w, "cell %d: more than %d encoder edges pending (the plant moved too fast for the "
                                "window)", j + 1, SAM_PINQ);
                cur = next;
            }
            w->count[j][ch] = cur;
        }
    }
    (void)t1;
    return 0;
}

/* ---------------------------------------------------------------- faults */

static void fault_schedule(sam_world_t *w, int mcu)
{
    uint64_t t = SAM_NEVER;
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->mcu != mcu || f->ended)
            continue;
        uint64_t due = !f->started                                                    ? f->t0
                       : (f->kind == SAM_FAULT_EDGE_STORM || f->kind == SAM_FAULT_SPIN) ? f->next
                                                                                     : f->t1;
        if (due < t)
            t = due;
    }
    sam_slot_set(w->mcu[mcu], SAM_SLOT_FAULT, t);
}

void sam_tc_stop_clock(sam_mcu_t *m, const char *name);

void sam_world_fault_fire(sam_mcu_t *m)
{
    sam_world_t *w = m->w;
    uint64_t now = sam_now(m);
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->mcu != m->id || f->ended)
            continue;
        if (!f->started && now >= f->t0) {
            f->started = 1;
            if (f->kind == SAM_FAULT_HARDFAULT) {
                sam_note(m, "%s: injected HardFault at t = %.6f s", m->name, (double)now / (double)SAM_TU_HZ);
                sam_irq_pend_sys(m, 3);
                f->ended = 1;
            } else if (f->kind == SAM_FAULT_RESET) {
                sam_note(m, "%s: reset requested from outside at t = %.6f s", m->name, (double)now / (double)SAM_TU_HZ);
                sam_mcu_system_reset(m, PM_RCAUSE_SYST);
                f->ended = 1;
            } else if (f->kind == SAM_FAULT_TICK_DEAD) {
                sam_note(m, "%s: injected loss of the TC3 clock at t = %.6f s", m->name,
                               (double)now / (double)SAM_TU_HZ);
                sam_tc_stop_clock(m, "TC3");
                f->ended = 1;
            } else if (f->kind == SAM_FAULT_EDGE_STORM || f->kind == SAM_FAULT_SPIN) {
                f->next = f->t0;
            }
        }
        if (f->started && !f->ended && f->kind == SAM_FAULT_SPIN) {
            int j = m->cell, ch = f->arg2 & 1, amplitude = f->arg2 >> 1;
            uint64_t dt = tu_of(1.0 / fabs(f->arg));
            if (!f->dir)
                f->dir = f->arg > 0 ? 1 : -1;
            while (f->next <= now && f->next < f->t1) {
                if (amplitude && f->leg == amplitude) {   /* the end of a leg: back the other way */
                    f->dir = -f->dir;
                    f->leg = 0;
                }
                int32_t cur = w->count[j][ch], next = cur + f->dir;
                f->leg++;
                int g0 = he_gray(cur), g1 = he_gray(next), chan = (g0 ^ g1) & 2 ? 0 : 1;
                sam_world_pinq_push(w, m->id, f->next, w->cfg.pin_enc[ch][chan], chan == 0 ? (g1 >> 1) & 1 : g1 & 1);
                w->count[j][ch] = next;
                f->next += dt;
            }
            if (f->next >= f->t1)
                f->ended = 1;
        }
        if (f->started && !f->ended && f->kind == SAM_FAULT_EDGE_STORM) {
            int pin = w->cfg.pin_enc[f->arg2][0];
            while (f->next <= now && f->next < f->t1) {
                /* a glitch pair: channel A toggles and comes back 1 us later */
                sam_world_pinq_push(w, m->id, f->next, pin, 2);
                sam_world_pinq_push(w, m->id, f->next + tu_of(1e-6), pin, 2);
                f->next += tu_of(1.0 / f->arg);
            }
            if (f->next >= f->t1)
                f->ended = 1;
        }
    }
    fault_schedule(w, m->id);
}

/* world-level faults, applied at their times (a round ends there) */
static int world_fault_level(int kind)
{
    return kind == SAM_FAULT_STUCK_SDA || kind == SAM_FAULT_SILENT || kind == SAM_FAULT_USB_NO_READ;
}

static uint64_t next_world_fault(const sam_world_t *w)
{
    uint64_t t = SAM_NEVER;
    for (int k = 0; k < w->nfault; k++) {
        const sam_fault_t *f = &w->fault[k];
        if (f->ended || !world_fault_level(f->kind))
            continue;
        uint64_t due = f->started ? f->t1 : f->t0;
        if (due < t)
            t = due;
    }
    return t;
}

static void lines_changed(sam_world_t *w)
{
    if (w->primary_mcu < 0)
        return;
    sam_mcu_t *p = w->mcu[w->primary_mcu];
    uint64_t saved = p->t_blk;
    p->t_blk = w->t;
    sam_bus_lines_changed(p);
    p->t_blk = saved;
}

static void world_faults(sam_world_t *w)
{
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->ended || !world_fault_level(f->kind))
            continue;
        sam_mcu_t *m = f->mcu >= 0 ? w->mcu[f->mcu] : NULL;
        if (!f->started && w->t >= f->t0) {
            f->started = 1;
            if (f->kind == SAM_FAULT_STUCK_SDA) {
                w->bus.sda_stuck = 1;
                sam_world_note(w, "bus: SDA held low from t = %.6f s", (double)w->t / (double)SAM_TU_HZ);
            } else if (f->kind == SAM_FAULT_SILENT && m) {
                m->t_blk = w->t;
                sam_world_pins_will_change(m);
                sam_bus_power_lost(m);
                m->halted = 1;
                sam_world_note(w, "%s: power lost at t = %.6f s", m->name, (double)w->t / (double)SAM_TU_HZ);
            } else if (f->kind == SAM_FAULT_USB_NO_READ) {
                w->usb[f->mcu].no_read = 1;
            }
            lines_changed(w);
        }
        if (f->started && w->t >= f->t1) {
            f->ended = 1;
            if (f->kind == SAM_FAULT_STUCK_SDA) {
                w->bus.sda_stuck = 0;
                sam_world_note(w, "bus: SDA released at t = %.6f s", (double)w->t / (double)SAM_TU_HZ);
            } else if (f->kind == SAM_FAULT_SILENT && m) {
                m->t = w->t;
                sam_world_note(w, "%s: power back at t = %.6f s", m->name, (double)w->t / (double)SAM_TU_HZ);
                sam_mcu_power_on_reset(m);
            } else if (f->kind == SAM_FAULT_USB_NO_READ) {
                w->usb[f->mcu].no_read = 0;
            }
            lines_changed(w);
        }
    }
}

int sam_world_fault(sam_world_t *w, int32_t kind, int32_t mcu, uint64_t t0, uint64_t t1, double arg, int32_t arg2)
{
    if (kind < 0 || kind >= SAM_FAULT_COUNT)
        return fail(w, "fault kind %d: expected 0..%d", kind, SAM_FAULT_COUNT - 1);
    if (kind != SAM_FAULT_STUCK_SDA && (mcu < 0 || mcu >= w->nmcu || !w->mcu[mcu]))
        return fail(w, "fault on board %d: no such board", mcu);
    if (t1 < t0 || t0 < w->t)
        return fail(w, "fault window [%llu, %llu) tu: must start at or after now (%llu) and not end before it starts",
                    (unsigned long long)t0, (unsigned long long)t1, (unsigned long long)w->t);
    if (kind == SAM_FAULT_EDGE_STORM && (!(arg > 0 && arg <= 400000) || arg2 < 0 || arg2 > 1))
        return fail(w, "edge storm: rate %g Hz must be in (0, 400000], encoder %d 0 (alpha) or 1 (beta)", arg, arg2);
    if (kind == SAM_FAULT_SPIN) {
        if (!(fabs(arg) >= 1 && fabs(arg) <= 1e6) || arg2 < 0 || (arg2 >> 1) > 1000000 || w->mcu[mcu]->cell < 0)
            return fail(w, "spin: rate %g counts/s must be 1..1e6 in size, on a cell's encoder", arg);
        if (w->plant_start != SAM_NEVER)
            return fail(w, "spin: the plant runs (it drives the encoders itself)");
    }
    int slot = w->nfault;
    for (int k = 0; slot >= SAM_MAX_FAULTS && k < w->nfault; k++)   /* full: an ended one's place is taken */
        if (w->fault[k].ended)
            slot = k;
    if (slot >= SAM_MAX_FAULTS)
        return fail(w, "more than %d faults", SAM_MAX_FAULTS);
    if (slot == w->nfault)
        w->nfault++;
    sam_fault_t *f = &w->fault[slot];
    memset(f, 0, sizeof *f);
    f->kind = kind;
    f->mcu = mcu;
    f->t0 = t0;
    f->t1 = t1;
    f->arg = arg;
    f->arg2 = arg2;
    if (mcu >= 0 && kind != SAM_FAULT_STUCK_SDA && kind != SAM_FAULT_SILENT && kind != SAM_FAULT_USB_NO_READ)
        fault_schedule(w, mcu);
    return 0;
}

/* ---------------------------------------------------------------- life cycle */

int sam_world_new(sam_world_t **out, const sam_world_cfg_t *cfg)
{
    *out = NULL;
    sam_world_t *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    *out = w;
    w->cfg = *cfg;
    if (cfg->ncells < 1 || cfg->ncells > 16)
        return fail(w, "ncells = %d: expected 1..16", cfg->ncells);
    if (!cfg->plant || !cfg->x || !cfg->v || cfg->plant->n != cfg->ncells)
        return fail(w, "the plant must exist and have ncells cells");
    if (!(cfg->window_s > 0 && cfg->window_s <= 0.01) || cfg->substeps < 1 || cfg->substeps > 10000)
        return fail(w, "window_s = %g (0 < W <= 10 ms), substeps = %d (1..10000)", cfg->window_s, cfg->substeps);
    if (cfg->cycle_model != SAM_CYCLES_CACHE && cfg->cycle_model != SAM_CYCLES_WORST)
        return fail(w, "cycle_model = %d: expected %d (cache) or %d (worst)", cfg->cycle_model, SAM_CYCLES_CACHE,
                    SAM_CYCLES_WORST);
    if (cfg->cyc_exc_entry < 1 || cfg->cyc_exc_entry > 100 || cfg->cyc_exc_exit < 1 || cfg->cyc_exc_exit > 100 ||
        cfg->cyc_apb < 0 || cfg->cyc_apb > 100)
        return fail(w, "cycle model: exception entry %d, return %d, APB access %d cycles (expected 1..100, 0..100)",
                    cfg->cyc_exc_entry, cfg->cyc_exc_exit, cfg->cyc_apb);
    if (!(cfg->supply_v > 0) || !(cfg->kt > 0) || !(cfg->counts_per_rad > 0))
        return fail(w, "supply_v, kt and counts_per_rad must be > 0");
    const int32_t *pins[] = {&cfg->pin_nsleep, &cfg->pin_ph[0], &cfg->pin_ph[1], &cfg->pin_en[0], &cfg->pin_en[1],
                             &cfg->pin_enc[0][0], &cfg->pin_enc[0][1], &cfg->pin_enc[1][0], &cfg->pin_enc[1][1],
                             &cfg->pin_sda, &cfg->pin_scl};
    for (size_t k = 0; k < sizeof pins / sizeof pins[0]; k++)
        if (*pins[k] < 0 || *pins[k] > 63)
            return fail(w, "board wiring: pin %d outside PA00..PB31", *pins[k]);
    w->window_tu = tu_of(cfg->window_s);
    w->round_tu = cfg->round_s > 0 ? tu_of(cfg->round_s) : w->window_tu;
    if (!(cfg->round_s >= 0) || w->round_tu == 0)
        return fail(w, "round_s = %g: expected 0 (the window) or a positive time", cfg->round_s);
    w->plant_start = SAM_NEVER;
    w->primary_mcu = -1;
    for (int j = 0; j < 16; j++)
        w->cell_mcu[j] = -1;
    w->xprev = calloc(2 * (size_t)cfg->ncells, sizeof(double));
    if (!w->xprev)
        return fail(w, "out of memory");
    for (int j = 0; j < cfg->ncells; j++)
        for (int ch = 0; ch < 2; ch++)
            w->count[j][ch] = (int32_t)floor(cfg->x[ch * cfg->ncells + j] * cfg->counts_per_rad);
    sam_bus_init(w);
    pin_tcc_table();
    if (cfg->threads < 1 || cfg->threads > SAM_MAX_THREADS)
        return fail(w, "threads = %d: expected 1..%d", cfg->threads, SAM_MAX_THREADS);
    if (pool_start(w, cfg->threads))
        return -1;
    sam_usb_world_init(w);
    return 0;
}

void sam_world_free(sam_world_t *w)
{
    if (!w)
        return;
    pool_stop(w);
    for (int i = 0; i < SAM_MAX_MCU; i++)
        if (w->mcu[i]) {
            sam_mcu_free(w->mcu[i]);
            free(w->mcu[i]);
        }
    free(w->xprev);
    free(w);
}

/* The factory rows the start-up code reads: the NVM software calibration row (NVMCTRL_OTP4, 0x00806020: ADC
 * linearity and bias, OSC32K, USB pad and DFLL48M coarse calibration, typical values) and the 128-bit serial
 * number (0x0080A00C, 0x0080A040..48), unique per board. */
static void nvm_rows(sam_mcu_t *m)
{
    uint8_t *n = m->nvm;
    memset(n, 0xFF, SAM_NVM_SIZE);
    uint64_t cal = 0;
    cal |= (uint64_t)0x1Du << 27;   /* ADC LINEARITY */
    cal |= (uint64_t)0x4u << 35;    /* ADC BIASCAL */
    cal |= (uint64_t)0x40u << 38;   /* OSC32K CAL */
    cal |= (uint64_t)0x9u << 45;    /* USB TRANSN */
    cal |= (uint64_t)0x19u << 50;   /* USB TRANSP */
    cal |= (uint64_t)0x5u << 55;    /* USB TRIM */
    cal |= (uint64_t)0x1Cu << 58;   /* DFLL48M COARSE */
    for (int b = 0; b < 8; b++)
        n[0x6020 + b] = (uint8_t)(cal >> (8 * b));
    uint32_t serial[4] = {0x4D43584Fu, 0x49414F00u + (uint32_t)m->id, 0x53414D44u, 0x3231AA00u + (uint32_t)m->id};
    uint32_t where[4] = {0xA00C, 0xA040, 0xA044, 0xA048};
    for (int k = 0; k < 4; k++)
        for (int b = 0; b < 4; b++)
            n[where[k] + (uint32_t)b] = (uint8_t)(serial[k] >> (8 * b));
}

int sam_world_load(sam_world_t *w, int mcu, const sam_image_t *img, const char *name, int32_t role, int32_t cell)
{
    const sam_seg_t *segs = img->segs;
    int32_t nsegs = img->nsegs;
    uint32_t code_end = img->code_end;
    if (mcu < 0 || mcu >= SAM_MAX_MCU || w->mcu[mcu])
        return fail(w, "board %d: out of range or already loaded", mcu);
    if (role == SAM_ROLE_CELL && (cell < 0 || cell >= w->cfg.ncells || w->cell_mcu[cell] >= 0))
        return fail(w, "board %d: cell %d out of range or taken", mcu, cell + 1);
    if (role == SAM_ROLE_PRIMARY && w->primary_mcu >= 0)
        return fail(w, "board %d: a second primary", mcu);
    if (!img->cost_core || !img->cost_wait || !img->cost_lit || !img->refund || code_end > SAM_FLASH_SIZE ||
        code_end < SAM_APP_BASE)
        return fail(w, "board %d: cycle tables missing or code end 0x%x outside flash", mcu, code_end);
    sam_mcu_t *m = calloc(1, sizeof *m);
    if (!m)
        return fail(w, "board %d: out of memory", mcu);
    if (sam_mcu_init(m, w, mcu)) {
        fail(w, "board %d: %s", mcu, m->errmsg[0] ? m->errmsg : "cannot create the CPU or its memory");
        sam_mcu_free(m);
        free(m);
        return -1;
    }
    w->mcu[mcu] = m;
    if (mcu >= w->nmcu)
        w->nmcu = mcu + 1;
    snprintf(m->name, sizeof m->name, "%s", name);
    m->role = role;
    m->cell = role == SAM_ROLE_CELL ? cell : -1;
    for (int k = 0; k < nsegs; k++) {
        if (segs[k].addr < SAM_APP_BASE || segs[k].addr + segs[k].len > SAM_FLASH_SIZE)
            return fail(w, "board %d: image segment at 0x%x (+%u) outside the application flash", mcu, segs[k].addr,
                        segs[k].len);
        memcpy(m->flash + segs[k].addr, segs[k].data, segs[k].len);
    }
    m->entry_sp = img->entry_sp;
    m->entry_pc = img->entry_pc;
    m->cost_core = img->cost_core;
    m->cost_wait = img->cost_wait;
    m->cost_lit = img->cost_lit;
    m->cycle_model = w->cfg.cycle_model;
    m->refund = img->refund;
    m->app_end = code_end;
    /* static data end and heap break: unknown ones make the fast-forward compare the whole SRAM */
    m->heap_base = img->heap_base > SAM_RAM_BASE && img->heap_base <= SAM_RAM_BASE + SAM_RAM_SIZE
                       ? img->heap_base - SAM_RAM_BASE
                       : SAM_RAM_SIZE;
    m->brk_var = img->brk_var;
    m->ff.loop_pc = img->loop_pc;
    m->ff.enabled = w->cfg.ff && img->loop_pc != 0;
    nvm_rows(m);
    if (role == SAM_ROLE_CELL) {
        w->cell_mcu[cell] = mcu;
        /* the encoders drive their pins from power-up */
        for (int ch = 0; ch < 2; ch++) {
            int g = he_gray(w->count[cell][ch]);
            w->enc_level[cell][ch][0] = (uint8_t)((g >> 1) & 1);
            w->enc_level[cell][ch][1] = (uint8_t)(g & 1);
        }
    } else {
        w->primary_mcu = mcu;
    }
    m->t = m->pos = w->t;
    sam_mcu_power_on_reset(m);
    if (role == SAM_ROLE_CELL)
        for (int ch = 0; ch < 2; ch++)
            for (int k = 0; k < 2; k++)
                sam_pin_drive(m, w->cfg.pin_enc[ch][k], w->enc_level[cell][ch][k]);
    if (m->err)
        return fail(w, "%s", m->errmsg);
    return 0;
}

void sam_world_start_plant(sam_world_t *w, uint64_t t_start)
{
    w->plant_start = t_start;
    w->plant_t = 0.0;
}

static int run_board(sam_world_t *w, sam_mcu_t *m, uint64_t to, int *moved)
{
    if (m->pos >= to)
        return 0;
    *moved = 1;
    if (sam_mcu_run(m, to))
        return fail(w, "%s", m->errmsg);
    return 0;
}

/* ---------------------------------------------------------------- workers: cells that cannot affect anyone in a
 * phase run at the same time on several threads (each on its own Unicorn; what they touch is their own) */

#define SPIN_PAUSES 300    /* a worker waits this long for the next jobs before it sleeps */
#define SPIN_YIELDS 0
#define PARALLEL_MIN 4     /* fewer jobs run on the calling thread: waking workers costs more */

static void relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

static void do_jobs(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    for (;;) {
        int i = __atomic_fetch_add(&pl->next, 1, __ATOMIC_ACQ_REL);
        if (i >= pl->njobs)
            return;
        sam_mcu_run(pl->job[i], pl->job_to[i]);
    }
}

static void *worker_main(void *arg)
{
    sam_world_t *w = arg;
    sam_pool_t *pl = &w->pool;
    unsigned seen = 0;
    for (;;) {
        int spins = 0;
        while (__atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE) == seen && !__atomic_load_n(&pl->quit, __ATOMIC_ACQUIRE)) {
            if (++spins < SPIN_PAUSES) {
                relax();
            } else if (spins < SPIN_PAUSES + SPIN_YIELDS) {
                sched_yield();
            } else {
                pthread_mutex_lock(&pl->mu);
                pl->sleeping++;
                while (__atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE) == seen && !pl->quit)
                    pthread_cond_wait(&pl->cv, &pl->mu);
                pl->sleeping--;
                pthread_mutex_unlock(&pl->mu);
                spins = 0;
            }
        }
        if (__atomic_load_n(&pl->quit, __ATOMIC_ACQUIRE))
            return NULL;
        seen = __atomic_load_n(&pl->gen, __ATOMIC_ACQUIRE);
        do_jobs(w);
        __atomic_fetch_sub(&pl->busy, 1, __ATOMIC_ACQ_REL);
    }
}

static int pool_start(sam_world_t *w, int nthreads)
{
    sam_pool_t *pl = &w->pool;
    pl->nworkers = 0;
    if (nthreads <= 1)
        return 0;
    if (pthread_mutex_init(&pl->mu, NULL) || pthread_cond_init(&pl->cv, NULL))
        return fail(w, "threads: cannot create a mutex");
    pl->init = 1;
    for (int k = 0; k < nthreads - 1 && k < SAM_MAX_THREADS - 1; k++) {
        if (pthread_create(&pl->th[k], NULL, worker_main, w))
            return fail(w, "threads: cannot start worker %d of %d", k + 1, nthreads - 1);
        pl->nworkers++;
    }
    return 0;
}

static void pool_stop(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    if (!pl->init)
        return;
    pthread_mutex_lock(&pl->mu);
    __atomic_store_n(&pl->quit, 1, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&pl->cv);
    pthread_mutex_unlock(&pl->mu);
    for (int k = 0; k < pl->nworkers; k++)
        pthread_join(pl->th[k], NULL);
    pthread_cond_destroy(&pl->cv);
    pthread_mutex_destroy(&pl->mu);
    pl->init = 0;
}

/* Run the jobs (boards that cannot affect each other or anyone else until their target): on the workers and
 * this thread when there are workers and more than one job. */
static int run_jobs(sam_world_t *w)
{
    sam_pool_t *pl = &w->pool;
    if (pl->njobs == 0)
        return 0;
    pl->next = 0;
    if (pl->nworkers == 0 || pl->njobs < PARALLEL_MIN) {
        do_jobs(w);
    } else {
        __atomic_store_n(&pl->busy, pl->nworkers, __ATOMIC_RELEASE);
        pthread_mutex_lock(&pl->mu);   /* a worker checks gen and goes to sleep under this lock: no lost wake-up */
        __atomic_fetch_add(&pl->gen, 1, __ATOMIC_ACQ_REL);
        if (pl->sleeping)
            pthread_cond_broadcast(&pl->cv);
        pthread_mutex_unlock(&pl->mu);
        do_jobs(w);
        for (int spins = 0; __atomic_load_n(&pl->busy, __ATOMIC_ACQUIRE) > 0; spins++) {
            if (spins < SPIN_PAUSES)
                relax();
            else
                sched_yield();
        }
    }
    for (int k = 0; k < pl->njobs; k++)   /* in board order: the same error whatever ran first */
        if (pl->job[k]->err)
            return fail(w, "%s", pl->job[k]->errmsg);
    return 0;
}

/* Every board from w->t to `target`, each as far as the others let it at a time (see the top of this file). */
static int round_to(sam_world_t *w, uint64_t target)
{
    sam_mcu_t *p = w->primary_mcu >= 0 ? w->mcu[w->primary_mcu] : NULL;
    sam_pool_t *pl = &w->pool;
    for (;;) {
        int moved = 0, behind = 0;
        if (p) {
            uint64_t h = target;
            for (int i = 0; i < w->nmcu; i++)
                if (w->mcu[i] && w->mcu[i] != p) {
                    uint64_t e = sam_bus_eot_slave(w->mcu[i]);
                    h = e < h ? e : h;
                }
            if (run_board(w, p, h, &moved))
                return -1;
        }
        /* first, one at a time, the cells that may answer the primary (what they send may let the others run
         * further); then the others, which cannot send anything before their target, together */
        for (int i = 0; i < w->nmcu; i++) {
            sam_mcu_t *m = w->mcu[i];
            if (!m || m == p || sam_bus_eot_slave(m) == SAM_NEVER)
                continue;
            uint64_t h = p ? sam_bus_eot_master(p) : SAM_NEVER;
            if (run_board(w, m, h < target ? h : target, &moved))
                return -1;
        }
        uint64_t h = p ? sam_bus_eot_master(p) : SAM_NEVER;
        h = h < target ? h : target;
        pl->njobs = 0;
        for (int i = 0; i < w->nmcu; i++) {
            sam_mcu_t *m = w->mcu[i];
            if (!m || m == p || m->pos >= h || sam_bus_eot_slave(m) != SAM_NEVER)
                continue;
            moved = 1;
            if (sam_mcu_idle_to(m, h))
                continue;   /* parked through h: nothing to run */
            pl->job[pl->njobs] = m;
            pl->job_to[pl->njobs++] = h;
        }
        if (run_jobs(w))
            return -1;
        for (int i = 0; i < w->nmcu; i++)
            if (w->mcu[i] && w->mcu[i]->pos < target)
                behind = 1;
        if (!behind)
            return 0;
        if (!moved)
            return fail(w, "the boards wait for each other at t = %.6f s (scheduling error)",
                        (double)w->t / (double)SAM_TU_HZ);
    }
}

int sam_world_run(sam_world_t *w, uint64_t t_end)
{
    if (w->err[0])
        return -1;
    while (w->t < t_end) {
        if (w->t >= w->next_window) {
            if (window(w, w->next_window))
                return -1;
            w->next_window += w->window_tu;
        }
        world_faults(w);
        uint64_t target = t_end < w->next_window ? t_end : w->next_window;
        uint64_t f = next_world_fault(w);
        if (f > w->t && f < target)
            target = f;
        if (w->t + w->round_tu < target)
            target = w->t + w->round_tu;
        int rc = round_to(w, target);
        collect_notes(w);
        if (rc)
            return -1;
        w->t = target;
    }
    return 0;
}

/* ---------------------------------------------------------------- queries */

int sam_world_mcu_info(const sam_world_t *w, int mcu, sam_mcu_info_t *o)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return -1;
    sam_mcu_t *m = w->mcu[mcu];
    memset(o, 0, sizeof *o);
    o->t_tu = m->ff.parked && m->t < w->t ? w->t : m->t;
    o->cycles = m->cycles;
    o->activity = m->act;
    uc_reg_read(m->uc, UC_ARM_REG_PC, &o->pc);
    uc_reg_read(m->uc, UC_ARM_REG_SP, &o->sp);
    uint32_t xpsr = 0;
    uc_reg_read(m->uc, UC_ARM_REG_XPSR, &xpsr);
    o->ipsr = xpsr & 0x3Fu;
    uc_reg_read(m->uc, UC_ARM_REG_PRIMASK, &o->primask);
    o->resets = m->resets;
    o->hardfaults = m->hardfaults;
    o->reset_cause = m->reset_cause;
    o->lockup = m->lockup;
    o->halted = m->halted;
    o->ff_passes_skipped = m->ff.passes_skipped;
    o->ff_cycles_skipped = m->ff.cycles_skipped;
    o->runs = m->runs;
    o->ff_parks = m->ff.parks;
    o->ff_checks = m->ff.checks;
    o->ff_misses = m->ff.misses;
    o->mmio_reads = m->mmio_reads;
    o->mmio_writes = m->mmio_writes;
    o->nvic_enabled = m->nvic.enabled;
    o->nvic_pending = m->nvic.pending;
    o->nvic_active = m->nvic.active;
    memcpy(o->nvic_prio, m->nvic.prio, 32);
    return 0;
}

int sam_world_read_mem(const sam_world_t *w, int mcu, uint32_t addr, uint8_t *buf, uint32_t len)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return -1;
    sam_mcu_t *m = w->mcu[mcu];
    if (addr >= SAM_RAM_BASE && addr + len <= SAM_RAM_BASE + SAM_RAM_SIZE) {
        memcpy(buf, m->ram + (addr - SAM_RAM_BASE), len);
        return 0;
    }
    if (addr + len <= SAM_FLASH_SIZE) {
        memcpy(buf, m->flash + addr, len);
        return 0;
    }
    return -1;
}

int sam_world_reg_value(const sam_world_t *w, int mcu, uint32_t ri, uint32_t *value)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu] || ri >= sam_nregs)
        return -1;
    *value = sam_reg_get(w->mcu[mcu], (int)ri);
    return 0;
}

const uint32_t *sam_world_touch(const sam_world_t *w, int mcu)
{
    return mcu >= 0 && mcu < SAM_MAX_MCU && w->mcu[mcu] ? w->mcu[mcu]->touch : NULL;
}

const uint64_t *sam_world_profile(sam_world_t *w, int mcu)
{
    if (mcu < 0 || mcu >= SAM_MAX_MCU || !w->mcu[mcu])
        return NULL;
    sam_mcu_t *m = w->mcu[mcu];
    if (!m->prof)
        m->prof = calloc(SAM_FLASH_SIZE / 2, sizeof *m->prof);
    return m->prof;
}

int sam_world_motor(const sam_world_t *w, int cell, int chain, double *volt, double *awake)
{
    if (cell < 0 || cell >= w->cfg.ncells || chain < 0 || chain > 1)
        return -1;
    *volt = w->motor[cell][chain].volt;
    *awake = w->motor[cell][chain].awake;
    return 0;
}
