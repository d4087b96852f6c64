/* Torque (+ optional back-EMF) to DRV8874 PH/EN command, with the voltage limit. */
#ifndef MC_DRIVE_H
#define MC_DRIVE_H

#include <stdint.h>

/*
 * Motor (SPEC 2):  tau = Kt * (V - omega/S_L),  Kt = 0.09 N*m / 12 V
 * so the voltage for a wanted torque is  V = tau/Kt + omega/S_L (the second term
 * only with back-EMF compensation on). Discrete form, d in Q16 of the supply:
 *
 *   d_tau  = ((clamp(tau, +-MC_TORQUE_CLAMP) >> 7) * tq_mul) >> 13
 *   d_bemf = clamp((dtheta_W * bemf_mul) >> 8, +-d_max)         (if enabled)
 *   d      = clamp(d_tau + d_bemf, +-d_max)
 *   duty   = min((|d| * pwm_top + 2^15) >> 16, duty_limit)       timer ticks
 *   dir    = d >= 0  (PH=1 forward/CCW),  enable = drive on (nSLEEP)
 *
 * d_max and duty_limit come from vmax_mv, itself capped by MC_VMAX_ABS_MV (5.86 V,
 * the DRV8874 2.1 A limit at 9 V): the cap is applied at configuration, at the
 * Q16 stage and again on the final tick count, so no input, parameter or
 * overflow can exceed it. A configuration is refused (MC_ERR_CONFIG) unless
 * tq_mul < 2^16, bemf_mul <= 2^20 and kt*vmax <= 0.0655 N*m (the torque clamp
 * then covers 2*vmax, so clamping never alters a command). Right shifts of negative values are arithmetic (GCC
 * and Clang define them so).
 */
#define MC_VMAX_ABS_MV 5860
#define MC_DRIVE_DTHETA_CLAMP 1024   /* counts per window, = MC_VEL_DIFF_CLAMP */

typedef struct {
    int32_t supply_mv;       /* motor supply, 4500..37000 mV (rig: 9000) */
    int32_t vmax_mv;         /* applied-voltage limit, 1..MC_VMAX_ABS_MV, <= supply */
    int32_t kt_unm_per_v;    /* stall torque / rated V, 1000..100000 (rig: 7500) */
    int32_t kv_mrad_per_vs;  /* speed constant S_L, 1000..1000000 (rig: 49800) */
    int32_t pwm_top;         /* PWM period in ticks, 255..4095 (20 kHz at 48 MHz: 2400) */
    int32_t ctrl_rate_hz;    /* control tick rate, 100..50000 (default 2000) */
    int32_t vel_window_log2; /* velocity window 2^n ticks, 0..8; -1 = ~16 ms auto */
} mc_drive_config_t;

typedef struct {
    int32_t tq_mul;      /* Q13 d_q16 per 128 TU */
    int32_t bemf_mul;    /* Q8 d_q16 per count of window difference */
    int32_t d_max;       /* Q16 */
    int32_t pwm_top;     /* ticks */
    int32_t duty_max;    /* ticks, floor(vmax*top/supply) */
    int32_t duty_limit;  /* ticks, user limit <= duty_max */
    int32_t vel_log2;    /* velocity window actually used */
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
/* Control path: torque in TU, window difference in counts. */
void mc_drive_command(const mc_drive_t *d, int32_t tau, int32_t dtheta_w,
                      int bemf_on, mc_drive_out_t *out);
/* The Q16 supply fraction before PWM quantisation (for tests and telemetry). */
int32_t mc_drive_q16(const mc_drive_t *d, int32_t tau, int32_t dtheta_w, int bemf_on);

#endif /* MC_DRIVE_H */
