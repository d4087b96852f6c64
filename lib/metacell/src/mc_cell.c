/* Cell control tick: faults, velocity, reaction law, perturbation, drive. */
#include <stddef.h>
#include "mc_cell.h"

#define MC_PERTURB_MAX_UNM 131000

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
    c->bemf_comp = 1;
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
        c->primed = 0; /* window length may have changed */
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
void mc_cell_set_bemf(mc_cell_t *c, int on) { c->bemf_comp = (uint8_t)(on != 0); }

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
    c->primed = 0;
}

void mc_cell_clear_faults(mc_cell_t *c)
{
    c->faults = 0;
    c->bucket[0] = c->bucket[1] = 0;
}

void mc_cell_report_driver_fault(mc_cell_t *c) { c->faults |= MC_FAULT_DRIVER; }

/* theta = clamp(pos - zero, +-MC_ANGLE_CLAMP), computed without overflow. */
static int32_t rel_angle(int32_t pos, int32_t zero)
{
    int32_t r = mc_sat_add_i32(pos, zero == INT32_MIN ? INT32_MAX : -zero);
    return mc_clamp_i32(r, -MC_ANGLE_CLAMP, MC_ANGLE_CLAMP);
}

static uint16_t check_encoder(mc_cell_t *c, int i, const mc_quad_snap_t *s, int32_t th)
{
    uint16_t f = 0;
    uint32_t fresh = s->errors - c->err_last[i];   /* modulo 2^32 */
    c->err_last[i] = s->errors;
    if (fresh > 255u)
        fresh = 255u;
    int32_t b = c->bucket[i] + (int32_t)(fresh << 8);
    b -= b > 0;
    c->bucket[i] = b;
    if (b > (c->enc_burst << 8))
        f |= (uint16_t)(MC_FAULT_ENCODER_A << i);
    if (th > c->runaway_counts || th < -c->runaway_counts)
        f |= (uint16_t)(MC_FAULT_RUNAWAY_A << i);
    if (s->saturated)
        f |= MC_FAULT_SATURATED;
    return f;
}

uint16_t mc_cell_tick(mc_cell_t *c, const mc_quad_snap_t *a, const mc_quad_snap_t *b)
{
    int32_t ta = rel_angle(a->pos, c->zero[0]);
    int32_t tb = rel_angle(b->pos, c->zero[1]);
    c->tick++;
    c->theta[0] = ta;
    c->theta[1] = tb;
    c->faults |= check_encoder(c, 0, a, ta) | check_encoder(c, 1, b, tb);

    if (!c->primed) {
        mc_vel_reset(&c->vel[0], c->drive.vel_log2, ta);
        mc_vel_reset(&c->vel[1], c->drive.vel_log2, tb);
        c->primed = 1;
    }
    int32_t wa = mc_vel_update(&c->vel[0], ta);
    int32_t wb = mc_vel_update(&c->vel[1], tb);

    int32_t ra, rb;
    mc_reaction_eval(&c->law, ta, tb, &ra, &rb);
    if (c->pert_ticks) {
        c->pert_ticks--;
        if (c->pert_chain == MC_ALPHA)
            ra += c->pert_torque;
        else
            rb += c->pert_torque;
    }
    c->torque[0] = ra;
    c->torque[1] = rb;

    if (c->faults || !c->enabled) {
        /* outputs off: nSLEEP low, EN low */
        c->out[0].duty = c->out[1].duty = 0;
        c->out[0].enable = c->out[1].enable = 0;
        c->out[0].dir = c->out[1].dir = 0;
        return c->faults;
    }
    mc_drive_command(&c->drive, ra, wa, c->bemf_comp, &c->out[0]);
    mc_drive_command(&c->drive, rb, wb, c->bemf_comp, &c->out[1]);
    return c->faults;
}
