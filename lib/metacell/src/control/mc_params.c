/* Configuration-time conversions (physical units -> fixed point). Not in the
 * control path: the only file of the library allowed to divide. */
#include "mc_reaction.h"
#include "../drivers/mc_drive.h"
#include "../sensors/mc_velocity.h"
#include "../mc_fixed.h"

/* The two factors below and the 15708 urad per count in mc_drive_configure are worked out for 400 counts per
 * revolution: a different encoder needs them recomputed. */
#if MC_COUNTS_PER_REV != 400
#error "mc_params.c: recompute MC_GAIN_PER_UNM_Q32, MC_ASTAR_PER_URAD_Q32 and 15708 for MC_COUNTS_PER_REV"
#endif

/* TU/count per uN*m/rad = (2*pi/400) * 32 = 0.50265482457..., as Q32. */
#define MC_GAIN_PER_UNM_Q32 2158886033LL
/* Q4 counts per urad = 400*16/(2*pi*1e6) = 1.01859163578813e-3, as Q32. */
#define MC_ASTAR_PER_URAD_Q32 4374818LL

static int32_t round_shift_i64(int64_t v, int s)
{
    int64_t half = (int64_t)1 << (s - 1);
    return (int32_t)(v >= 0 ? (v + half) >> s : -((-v + half) >> s));
}

int mc_reaction_set_raw(mc_reaction_t *out, int32_t g_ab, int32_t g_sigma,
                        int32_t g1, int32_t g2, int32_t astar_q4)
{
    if (!out)
        return MC_ERR_ARG;
    if (g_ab < -MC_GAIN_MAX || g_ab > MC_GAIN_MAX || g_sigma < -MC_GAIN_MAX ||
        g_sigma > MC_GAIN_MAX || g1 < -MC_GAIN_MAX || g1 > MC_GAIN_MAX ||
        g2 < -MC_GAIN_MAX || g2 > MC_GAIN_MAX)
        return MC_ERR_RANGE;
    if (astar_q4 < 0 || astar_q4 > MC_COUNTS_PER_REV * 16)
        return MC_ERR_RANGE;
    if (g1 <= 0 || g1 <= g2)
        return MC_ERR_SHAPE;
    mc_reaction_t r;
    r.g_ab = g_ab;
    r.g_sigma = g_sigma;
    r.g1 = g1;
    r.g2 = g2;
    r.astar_q4 = astar_q4;
    r.c1 = round_shift_i64((int64_t)g1 * astar_q4, MC_ASTAR_FRAC_BITS);
    *out = r;
    return MC_OK;
}

static int gain_from_unm(int32_t k_unm, int32_t *g)
{
    if (k_unm < -MC_K_MAX_UNM || k_unm > MC_K_MAX_UNM)
        return MC_ERR_RANGE;
    *g = round_shift_i64((int64_t)k_unm * MC_GAIN_PER_UNM_Q32, 32);
    return MC_OK;
}

int mc_reaction_from_phys(mc_reaction_t *out, const mc_reaction_phys_t *p)
{
    int32_t g_ab, g_sigma, g1, g2;
    if (!out || !p)
        return MC_ERR_ARG;
    if (gain_from_unm(p->k_ab_unm, &g_ab) || gain_from_unm(p->sigma_unm, &g_sigma) ||
        gain_from_unm(p->k1_unm, &g1) || gain_from_unm(p->k2_unm, &g2))
        return MC_ERR_RANGE;
    if (p->astar_urad < 0 || p->astar_urad > MC_ASTAR_MAX_URAD)
        return MC_ERR_RANGE;
    int32_t astar_q4 = round_shift_i64((int64_t)p->astar_urad * MC_ASTAR_PER_URAD_Q32, 32);
    return mc_reaction_set_raw(out, g_ab, g_sigma, g1, g2, astar_q4);
}

/* round(num * 2^s / den) by long division (no 64-bit overflow for num, den < 2^62). */
static uint64_t ratio_shift(uint64_t num, uint64_t den, int s)
{
    uint64_t q = num / den, r = num % den;
    for (int i = 0; i < s; i++) {
        q <<= 1;
        r <<= 1;
        if (r >= den) {
            q |= 1;
            r -= den;
        }
    }
    return q + (2 * r >= den);
}

/* Largest s in 0..30 with round(num*2^s/den) < limit; -1 if even s = 0 is too big. */
static int pick_shift(uint64_t num, uint64_t den, uint64_t limit, int32_t *m)
{
    int s = -1;
    for (int t = 0; t <= 30; t++) {
        uint64_t v = ratio_shift(num, den, t);
        if (v >= limit)
            break;
        s = t;
        *m = (int32_t)v;
    }
    return s;
}

void mc_drive_default_config(mc_drive_config_t *cfg)
{
    cfg->supply_mv = 9000;
    cfg->vmax_mv = MC_VMAX_ABS_MV;
    cfg->kt_unm_per_v = 7500;
    cfg->kv_mrad_per_vs = 49800;
    cfg->pwm_top = 2400;
    cfg->ctrl_rate_hz = 2000;
    cfg->vel_window_log2 = -1;
}

int mc_drive_configure(mc_drive_t *out, const mc_drive_config_t *c)
{
    if (!out || !c)
        return MC_ERR_ARG;
    if (c->supply_mv < 4500 || c->supply_mv > 37000 || c->vmax_mv < 1 ||
        c->vmax_mv > MC_VMAX_ABS_MV || c->vmax_mv > c->supply_mv ||
        c->kt_unm_per_v < 1000 || c->kt_unm_per_v > 100000 ||
        c->kv_mrad_per_vs < 1000 || c->kv_mrad_per_vs > 1000000 ||
        c->pwm_top < 255 || c->pwm_top > 4095 || c->ctrl_rate_hz < 100 ||
        c->ctrl_rate_hz > 50000 || c->vel_window_log2 < -1 || c->vel_window_log2 > 8)
        return MC_ERR_CONFIG;
    /* the torque clamp (2^22 TU = 0.131 N*m) must reach at least 2*vmax, so that
     * clamping the torque never changes a command (even against back-EMF) */
    if ((int64_t)c->kt_unm_per_v * c->vmax_mv > 65536000LL)
        return MC_ERR_CONFIG;
    /* the observer's velocity is counts/tick with w fraction bits (vel_window_log2 is
     * validated for old configurations but no longer selects anything) */
    int w = MC_VEL_OUT_LOG2;
    mc_drive_t d;
    /* m_t/2^s_t = 16 ticks * 128 TU [= 4e-6 N*m] / Kt / Vs * top
     *           = 16 * 4000 * top / (kt_unm_per_v * supply_mv) */
    uint64_t num_t = (uint64_t)64000u * (uint64_t)c->pwm_top;
    uint64_t den_t = (uint64_t)c->kt_unm_per_v * (uint64_t)c->supply_mv;
    d.s_t = pick_shift(num_t, den_t, 1u << 15, &d.m_t);
    /* m_b/2^s_b = 16 * (2 pi/400 rad) * f / 2^w / S_L / Vs * top   (velocity counts/tick Qw)
     *           = 16 * 15708 urad * f * top / (kv_mrad_per_vs * supply_mv * 2^w) */
    uint64_t num_b = (uint64_t)15708u * 16u * (uint64_t)c->ctrl_rate_hz * (uint64_t)c->pwm_top *
                     MC_BEMF_FRAC_NUM;
    uint64_t den_b = (((uint64_t)c->kv_mrad_per_vs * (uint64_t)c->supply_mv) << w) * MC_BEMF_FRAC_DEN;
    d.s_b = pick_shift(num_b, den_b, 1u << 18, &d.m_b);
    if (d.s_t < 0 || d.s_b < 0)
        return MC_ERR_CONFIG;
    d.pwm_top = c->pwm_top;
    d.duty_max = (int32_t)(((int64_t)c->vmax_mv * c->pwm_top) / c->supply_mv);
    d.duty_limit = d.duty_max;
    d.vel_log2 = w;
    *out = d;
    return MC_OK;
}

int32_t mc_drive_set_limit(mc_drive_t *d, int32_t duty_limit)
{
    d->duty_limit = mc_clamp_i32(duty_limit, 0, d->duty_max);
    return d->duty_limit;
}
