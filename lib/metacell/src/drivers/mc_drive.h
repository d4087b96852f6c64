/* Torque (+ optional back-EMF) to DRV8874 PH/EN command, with the voltage limit. */
#ifndef MC_DRIVE_H
#define MC_DRIVE_H

#include <stdint.h>
#include "../mc_fixed.h"
#include "../sensors/mc_velocity.h"

/*
 * Motor law (docs/physics.md#actuators):  tau = Kt * (V - omega/S_L),  Kt = 0.09 N*m / 12 V
 * so the voltage for a wanted torque is  V = tau/Kt + c * omega/S_L (the second term
 * only with back-EMF compensation on; c = MC_BEMF_FRAC_NUM/DEN = 15/16, see below),
 * and the PWM duty is V/V_supply*pwm_top.
 * Discrete form, straight into sixteenths of a PWM tick (one multiply per term):
 *
 *   t7   = (clamp(tau, +-MC_TORQUE_CLAMP) + 64) >> 7                128 TU units
 *   v16  = ((t7 * m_t) >> s_t) + ((dtheta_W * m_b) >> s_b)         (second term if on;
 *          dtheta_W = observer velocity, counts/tick with w = 6 fraction bits)
 *   v    = clamp((v16 + 8) >> 4, +-duty_limit)                      timer ticks
 *   duty = |v|,  dir = v >= 0 (PH=1 forward/CCW),  enable = 1 (nSLEEP high)
 *
 * m_t/2^s_t = 16 * 128 TU / Kt / V_supply * pwm_top and m_b/2^s_b = 16 * (2 pi/400)
 * * f_ctrl / 2^w / S_L / V_supply * pwm_top * c (w = MC_VEL_OUT_LOG2), chosen at configuration with
 * 2^14 <= m_t < 2^15 and 2^17 <= m_b < 2^18 (relative precision better than 2^-14).
 * Ranges: |t7| <= 2^15 + 1, |dtheta_W| <= MC_VEL_DIFF_MAX = 2^12, so both products
 * are < 2^30 and their sum < 2^31. Worst-case error against the real-valued
 * relation: 0.12 (t7 rounding, at pwm_top 4095) + 0.16 (multipliers) + 2/16
 * (floors) + 0.5 (final rounding) < 1 tick.
 *
 * duty_limit <= duty_max = floor(vmax * pwm_top / supply), vmax <= MC_VMAX_ABS_MV
 * (5.86 V, the DRV8874 2.1 A limit at 9 V): a single clamp on the final tick
 * count enforces the cap, so no input, parameter or overflow can exceed it. A
 * configuration is refused (MC_ERR_CONFIG) unless every field is in range,
 * kt*vmax <= 0.0655 N*m (the torque clamp, 2^22 TU = 0.131 N*m, then covers 2*vmax:
 * without back-EMF compensation it never alters a command; with it, the torque
 * saturation is part of the law) and m_b fits for some s_b >= 0. Right shifts
 * of negative values are arithmetic (GCC and Clang define them so).
 */
#define MC_VMAX_ABS_MV 5860

/* Fraction of the back-EMF term omega/S_L that compensation adds (7/8), folded into
 * m_b at configuration. The observer passes the 34 Hz long-wave oscillation with gain
 * 1.08 and the command is held for a tick after its sample; full compensation would
 * then leave the lattice at sigma = 9/125 with no damping margin on its long-wave
 * mode (it oscillates in the emulator), while 7/8 leaves about 1/20 of Kt/S_L there
 * and keeps the sigma = 14/125 limit cycle at the undamped lattice's period. */
#define MC_BEMF_FRAC_NUM 15u
#define MC_BEMF_FRAC_DEN 16u

typedef struct {
    int32_t supply_mv;       /* motor supply, 4500..37000 mV (rig: 9000) */
    int32_t vmax_mv;         /* applied-voltage limit, 1..MC_VMAX_ABS_MV, <= supply */
    int32_t kt_unm_per_v;    /* stall torque / rated V, 1000..100000 (rig: 7500) */
    int32_t kv_mrad_per_vs;  /* speed constant S_L, 1000..1000000 (rig: 49800) */
    int32_t pwm_top;         /* PWM period in ticks, 255..4095 (20 kHz at 48 MHz: 2400) */
    int32_t ctrl_rate_hz;    /* control tick rate, 100..50000 (default 2000) */
    int32_t vel_window_log2; /* -1..8, accepted and ignored: the former velocity window (the
                              * observer's output is counts/tick Q6, MC_VEL_OUT_LOG2) */
} mc_drive_config_t;

typedef struct {
    int32_t m_t;         /* torque multiplier, 2^14..2^15-1 */
    int32_t s_t;         /* its shift */
    int32_t m_b;         /* back-EMF multiplier, 2^17..2^18-1 (or smaller at s_b = 0) */
    int32_t s_b;         /* its shift */
    int32_t duty_limit;  /* ticks, user limit <= duty_max */
    int32_t duty_max;    /* ticks, floor(vmax*top/supply) */
    int32_t pwm_top;     /* ticks */
    int32_t vel_log2;    /* fraction bits w of the velocity input (MC_VEL_OUT_LOG2) */
} mc_drive_t;

typedef struct {
    uint16_t duty;    /* PWM compare value on EN, 0..pwm_top */
    uint8_t dir;      /* PH level */
    uint8_t enable;   /* driver awake (nSLEEP high) */
} mc_drive_out_t;

void mc_drive_default_config(mc_drive_config_t *cfg);
/* Validate and derive; on error *out is untouched. Configuration path (divides). */
int mc_drive_configure(mc_drive_t *out, const mc_drive_config_t *cfg);
/* Clamp the user PWM limit (ticks) to duty_max; returns the limit in force. */
int32_t mc_drive_set_limit(mc_drive_t *d, int32_t duty_limit);
/* Control path: torque in TU, velocity in counts/tick Qw (w = vel_log2) (any int32; it
 * is clamped to +-MC_VEL_DIFF_MAX first; sensors/mc_velocity.h supplies it). */
void mc_drive_command(const mc_drive_t *d, int32_t tau, int32_t dtheta_w,
                      int bemf_on, mc_drive_out_t *out);

#ifndef MC_CDEF
/* mc_drive_command for |dtheta_w| <= MC_VEL_DIFF_MAX; equations above. */
MC_INLINE void mc_drive_command_inl(const mc_drive_t *d, int32_t tau, int32_t dtheta_w,
                                    int bemf_on, mc_drive_out_t *out)
{
    /* clamp to [-2^22, 2^22 - 1]: the same t7 as the symmetric clamp, one test fewer */
    int32_t st = tau >> 31;
    if ((tau >> 22) != st)
        tau = st ^ (MC_TORQUE_CLAMP - 1);
    int32_t t7 = (tau + 64) >> 7;
    int32_t v = (t7 * d->m_t) >> d->s_t;
    if (bemf_on)
        v += (dtheta_w * d->m_b) >> d->s_b;
    v = mc_clamp_sym((v + 8) >> 4, d->duty_limit);
    int32_t sv = v >> 31;                     /* 0 or -1 */
    out->duty = (uint16_t)((v ^ sv) - sv);
    out->dir = (uint8_t)(sv + 1);
    out->enable = 1;
}
#endif

#endif /* MC_DRIVE_H */
