/* Faults injected from a scene: per board (edge storms, spins, HardFault, dead tick) and world-level (SDA, power, USB). */
#include <math.h>
#include <string.h>
#include "sam_core.h"
#include "sam_vendor_gen.h"

static uint64_t tu_of(double s) { return (uint64_t)llround(s * (double)SAM_TU_HZ); }

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
    sam_slot_set(w->mcu[mcu], w->fault_slot[mcu], t);
}

/* the faults' event source on a board: those that start, act or end now */
static void fault_fire(sam_mcu_t *m, void *ctx)
{
    (void)ctx;
    sam_world_t *w = m->w;
    uint64_t now = sam_now(m);
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->mcu != m->id || f->ended)
            continue;
        if (!f->started && now >= f->t0) {
            f->started = 1;
            f->t_fired = now;
            if (f->kind == SAM_FAULT_HARDFAULT) {
                sam_note(m, "%s: injected HardFault at t = %.6f s", m->name, (double)now / (double)SAM_TU_HZ);
                sam_irq_pend_sys(m, 3);
                f->ended = 1;
            } else if (f->kind == SAM_FAULT_RESET) {
                sam_note(m, "%s: reset requested from outside at t = %.6f s", m->name, (double)now / (double)SAM_TU_HZ);
                sam_mcu_system_reset(m, PM_RCAUSE_SYST);
                f->ended = 1;
            } else if (f->kind == SAM_FAULT_RESET_BUTTON) {
                sam_note(m, "%s: reset button at t = %.6f s", m->name, (double)now / (double)SAM_TU_HZ);
                sam_request_reset(m, PM_RCAUSE_EXT);
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

uint64_t sam_world_next_fault(const sam_world_t *w)
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

static void lines_changed(sam_world_t *w, int sda_fault)
{
    if (w->primary_mcu < 0)
        return;
    sam_mcu_t *p = w->mcu[w->primary_mcu];
    uint64_t saved = p->t_blk;
    p->t_blk = w->t;
    sam_bus_lines_changed(p);
    if (sda_fault >= 0)
        sam_bus_sda_fault(p, sda_fault);
    p->t_blk = saved;
}

/* A board's own faults that came due while it had no power take effect now, at its power-up, and are dated so. */
static void power_up_faults(sam_world_t *w, int mcu)
{
    int moved = 0;
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->mcu != mcu || f->started || f->ended || world_fault_level(f->kind) || f->t0 >= w->t)
            continue;
        int edges = f->kind == SAM_FAULT_EDGE_STORM || f->kind == SAM_FAULT_SPIN;
        if (edges && f->t1 <= w->t) {   /* edges on the cable, all while the board was off: it saw none of them */
            f->started = f->ended = 1;
            f->t_fired = f->t0;
            continue;
        }
        sam_world_note(w, "%s: a fault due at t = %.6f s while it had no power takes effect at power-up", w->mcu[mcu]->name,
                       (double)f->t0 / (double)SAM_TU_HZ);
        if (f->t1 < w->t)
            f->t1 = w->t;
        f->t0 = w->t;
        moved = 1;
    }
    if (moved)
        fault_schedule(w, mcu);
}

void sam_world_faults_apply(sam_world_t *w)
{
    for (int k = 0; k < w->nfault; k++) {
        sam_fault_t *f = &w->fault[k];
        if (f->ended || !world_fault_level(f->kind))
            continue;
        sam_mcu_t *m = f->mcu >= 0 ? w->mcu[f->mcu] : NULL;
        if (!f->started && w->t >= f->t0) {
            f->started = 1;
            f->t_fired = w->t;
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
            lines_changed(w, f->kind == SAM_FAULT_STUCK_SDA ? 1 : -1);
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
                power_up_faults(w, f->mcu);
            } else if (f->kind == SAM_FAULT_USB_NO_READ) {
                w->usb[f->mcu].no_read = 0;
            }
            lines_changed(w, f->kind == SAM_FAULT_STUCK_SDA ? 0 : -1);
        }
    }
}

int sam_world_fault(sam_world_t *w, int32_t kind, int32_t mcu, uint64_t t0, uint64_t t1, double arg, int32_t arg2)
{
    if (kind < 0 || kind >= SAM_FAULT_COUNT)
        return sam_world_fail(w, "fault kind %d: expected 0..%d", kind, SAM_FAULT_COUNT - 1);
    if (kind != SAM_FAULT_STUCK_SDA && (mcu < 0 || mcu >= w->nmcu || !w->mcu[mcu]))
        return sam_world_fail(w, "fault on board %d: no such board", mcu);
    if (t1 < t0 || t0 < w->t)
        return sam_world_fail(w, "fault window [%llu, %llu) tu: must start at or after now (%llu) and not end before it starts",
                    (unsigned long long)t0, (unsigned long long)t1, (unsigned long long)w->t);
    if (kind == SAM_FAULT_EDGE_STORM && (!(arg > 0 && arg <= 400000) || arg2 < 0 || arg2 > 1))
        return sam_world_fail(w, "edge storm: rate %g Hz must be in (0, 400000], encoder %d 0 (alpha) or 1 (beta)", arg, arg2);
    if (kind == SAM_FAULT_SPIN) {
        if (!(fabs(arg) >= 1 && fabs(arg) <= 1e6) || arg2 < 0 || (arg2 >> 1) > 1000000 || w->mcu[mcu]->cell < 0)
            return sam_world_fail(w, "spin: rate %g counts/s must be 1..1e6 in size, on a cell's encoder", arg);
        if (w->plant_start != SAM_NEVER)
            return sam_world_fail(w, "spin: the plant runs (it drives the encoders itself)");
    }
    /* a board whose clock a stall has moved past t0 (NVMCTRL programming a row: up to 0.85 ms) meets the action at its
     * own time, the window moved with it: never in a board's past (World.reset and the USB host's api_time give an
     * outside action 50 us after the world's time, which such a board has already passed) */
    if (mcu >= 0 && kind != SAM_FAULT_STUCK_SDA && kind != SAM_FAULT_SILENT && kind != SAM_FAULT_USB_NO_READ &&
        w->mcu[mcu]->t > t0) {
        uint64_t late = w->mcu[mcu]->t - t0;
        t0 += late;
        t1 = t1 > SAM_NEVER - late ? SAM_NEVER : t1 + late;
    }
    int slot = w->nfault;
    for (int k = 0; slot >= SAM_MAX_FAULTS && k < w->nfault; k++)   /* full: an ended one's place is taken */
        if (w->fault[k].ended)
            slot = k;
    if (slot >= SAM_MAX_FAULTS)
        return sam_world_fail(w, "more than %d faults", SAM_MAX_FAULTS);
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
    f->t_fired = SAM_FAULT_UNFIRED;
    if (mcu >= 0 && kind != SAM_FAULT_STUCK_SDA && kind != SAM_FAULT_SILENT && kind != SAM_FAULT_USB_NO_READ)
        fault_schedule(w, mcu);
    return 0;
}

int sam_world_nfaults(const sam_world_t *w) { return w->nfault; }

int sam_world_fault_info(const sam_world_t *w, int k, sam_fault_info_t *out)
{
    if (k < 0 || k >= w->nfault)
        return -1;
    const sam_fault_t *f = &w->fault[k];
    out->kind = f->kind;
    out->mcu = f->mcu;
    out->ended = f->ended;
    out->t0 = f->t0;
    out->t1 = f->t1;
    out->fired = f->started;
    out->t_fired = f->started ? f->t_fired : 0;
    return 0;
}

/* The faults' event source on a board (registered when the world loads it). */
void sam_world_faults_init(sam_mcu_t *m)
{
    m->w->fault_slot[m->id] = sam_source_add(m, fault_fire, NULL, NULL, 0);
}
