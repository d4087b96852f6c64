/* Cell control tick: faults, velocity, reaction law, perturbation, drive. */
#include <stddef.h>
#include "mc_cell.h"

void mc_cell_default_params(mc_reaction_phys_t *p)
{
    p->k_ab_unm = 20000;     /* 1/50 */
    p->sigma_unm = 72000;    /* 9/125 */
    p->k1_unm = 60000;       /* 3/50 */
    p->k2_unm = -60000;      /* -3/50 */
    p->astar_urad = 1178097; /* 3*pi/8 */
}

void mc_cell_init(mc_cell_t *c)
{
    mc_reaction_phys_t p;
    mc_drive_config_t d;
    uint8_t *raw = (uint8_t *)c;
    for (size_t i = 0; i < sizeof(*c); i++)
        raw[i] = 0;
    mc_cell_default_params(&p);
    mc_reaction_from_phys(&c->law, &p);
    mc_drive_default_config(&d);
    mc_drive_configure(&c->drive, &d);
    c->runaway_counts = 800;
    c->enc_burst = 8;
    c->bemf_comp = 0;   /* off by default: see mc_cell.h */
    mc_vel_reset(&c->vel, 0, 0);
}

int mc_cell_set_params(mc_cell_t *c, const mc_reaction_phys_t *p)
{
    return mc_reaction_from_phys(&c->law, p);
}

int mc_cell_set_drive(mc_cell_t *c, const mc_drive_config_t *cfg)
{
    int32_t limit = c->drive.duty_limit == c->drive.duty_max ? -1 : c->drive.duty_limit;
    int rc = mc_drive_configure(&c->drive, cfg);
    if (rc == MC_OK) {
        if (limit >= 0)
            mc_drive_set_limit(&c->drive, limit);
    }
    return rc;
}

int mc_cell_set_runaway(mc_cell_t *c, int32_t counts)
{
    if (counts < 1 || counts > MC_ANGLE_CLAMP)
        return MC_ERR_RANGE;
    c->runaway_counts = counts;
    return MC_OK;
}

void mc_cell_enable(mc_cell_t *c, int on) { c->enabled = (uint8_t)(on != 0); }
void mc_cell_set_bemf(mc_cell_t *c, int on)
{
    /* the observer only runs while compensation is on: restart it from the last angles, at rest */
    if (on && !c->bemf_comp)
        mc_vel_reset(&c->vel, c->theta[0], c->theta[1]);
    c->bemf_comp = (uint8_t)(on != 0);
}

int mc_cell_perturb(mc_cell_t *c, int chain, int32_t torque_unm, uint32_t ticks)
{
    if ((chain != MC_ALPHA && chain != MC_BETA) || torque_unm < -MC_PERTURB_MAX_UNM ||
        torque_unm > MC_PERTURB_MAX_UNM)
        return MC_ERR_RANGE;
    c->pert_chain = (uint8_t)chain;
    c->pert_torque = torque_unm * (1 << MC_TORQUE_FRAC_BITS);
    c->pert_ticks = ticks;
    return MC_OK;
}

void mc_cell_zero(mc_cell_t *c, int32_t pos_a, int32_t pos_b)
{
    c->zero[0] = pos_a;
    c->zero[1] = pos_b;
    c->theta[0] = c->theta[1] = 0;
    mc_vel_reset(&c->vel, 0, 0);
}

void mc_cell_clear_faults(mc_cell_t *c)
{
    c->faults = 0;
    c->bucket[0] = c->bucket[1] = 0;
}

void mc_cell_report_driver_fault(mc_cell_t *c) { c->faults |= MC_FAULT_DRIVER; }

/*
 * theta = pos - zero, limited to +-runaway (<= MC_ANGLE_CLAMP): a limited angle
 * latches the runaway fault, so the clamp that keeps the law's arithmetic in
 * range is the runaway check itself. The subtraction is done modulo 2^32 and a
 * signed overflow (pos, zero of opposite signs, result of the wrong sign) is
 * caught and saturated, never wrapped.
 */
MC_INLINE int32_t rel_angle(int32_t pos, int32_t zero, int32_t lim, uint16_t *f, uint16_t flag)
{
    int32_t d = (int32_t)((uint32_t)pos - (uint32_t)zero);
    if (((pos ^ zero) & (pos ^ d)) < 0)
        d = pos < 0 ? INT32_MIN / 2 : INT32_MAX / 2;
    if ((uint32_t)d + (uint32_t)lim > 2u * (uint32_t)lim) {   /* |d| > lim */
        d = d < 0 ? -lim : lim;
        *f |= flag;
    }
    return d;
}

/*
 * Encoder-error leaky bucket (see mc_cell.h), evaluated only on a tick where an
 * error counter moved; the decay of one per tick since the last error is
 * applied then, so a quiet tick costs one comparison:
 *   bucket = max(0, bucket - (tick - err_tick)) + 256*min(new errors, 255)
 *   fault when bucket > 256*enc_burst
 */
static uint16_t encoder_faults(mc_cell_t *c, uint32_t ea, uint32_t eb)
{
    uint16_t f = 0;
    uint32_t e[2] = {ea, eb};
    for (int i = 0; i < 2; i++) {
        uint32_t fresh = e[i] - c->err_last[i];      /* modulo 2^32 */
        if (!fresh)
            continue;
        uint32_t idle = c->tick - c->err_tick[i];
        int32_t bk = (uint32_t)c->bucket[i] > idle ? c->bucket[i] - (int32_t)idle : 0;
        if (fresh > 255u)
            fresh = 255u;
        bk += (int32_t)(fresh << 8);
        c->bucket[i] = bk;
        c->err_last[i] = e[i];
        c->err_tick[i] = c->tick;
        if (bk > (c->enc_burst << 8))
            f |= (uint16_t)(MC_FAULT_ENCODER_A << i);
    }
    return f;
}

/* Drive with back-EMF compensation: observer velocities (counts/tick Q6) add
 * omega/S_L to each command. Out of line, so that the default path keeps its registers. */
MC_NOINLINE void drive_bemf(mc_cell_t *c, mc_vel_t *o, int32_t ta, int32_t tb)
{
    int32_t wa, wb;
    mc_vel_update_inl(o, ta, tb, &wa, &wb);
    mc_drive_command_inl(&c->drive, c->torque[0], wa, 1, &c->out[0]);
    mc_drive_command_inl(&c->drive, c->torque[1], wb, 1, &c->out[1]);
}

uint16_t mc_cell_tick(mc_cell_t *c, const mc_quad_snap_t *a, const mc_quad_snap_t *b)
{
    uint16_t f = c->faults;
    int32_t lim = c->runaway_counts;
    int32_t ta = rel_angle(a->pos, c->zero[0], lim, &f, MC_FAULT_RUNAWAY_A);
    int32_t tb = rel_angle(b->pos, c->zero[1], lim, &f, MC_FAULT_RUNAWAY_B);
    c->tick++;
    c->theta[0] = ta;
    c->theta[1] = tb;
    uint32_t ea = a->errors, eb = b->errors;
    if ((ea ^ c->err_last[0]) | (eb ^ c->err_last[1]))
        f |= encoder_faults(c, ea, eb);
    if (a->saturated | b->saturated)
        f |= MC_FAULT_SATURATED;
    c->faults = f;

    int32_t ra, rb;
    mc_reaction_eval_inl(&c->law, ta, tb, &ra, &rb);
    if (c->pert_ticks) {
        c->pert_ticks--;
        if (c->pert_chain == MC_ALPHA)
            ra += c->pert_torque;
        else
            rb += c->pert_torque;
    }
    c->torque[0] = ra;
    c->torque[1] = rb;

    if (f || !c->enabled) {
        /* outputs off: nSLEEP low, EN low */
        c->out[0].duty = c->out[1].duty = 0;
        c->out[0].enable = c->out[1].enable = 0;
        c->out[0].dir = c->out[1].dir = 0;
        return f;
    }
    if (c->bemf_comp) {
        drive_bemf(c, &c->vel, ta, tb);
        return f;
    }
    mc_drive_command_inl(&c->drive, ra, 0, 0, &c->out[0]);
    mc_drive_command_inl(&c->drive, rb, 0, 0, &c->out[1]);
    return f;
}
