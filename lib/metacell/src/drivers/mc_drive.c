/* Torque to PWM/DIR command (control path; equations in mc_drive.h). */
#include "mc_drive.h"
#include "../mc_fixed.h"

int32_t mc_drive_q16(const mc_drive_t *d, int32_t tau, int32_t dtheta_w, int bemf_on)
{
    tau = mc_clamp_i32(tau, -MC_TORQUE_CLAMP, MC_TORQUE_CLAMP);
    /* |tau >> 7| <= 2^15 and tq_mul < 2^16: product < 2^31 */
    int32_t q = ((tau >> 7) * d->tq_mul) >> 13;
    if (bemf_on) {
        /* |dtheta| <= 2^10 and bemf_mul <= 2^20: product <= 2^30 */
        int32_t dt = mc_clamp_i32(dtheta_w, -MC_DRIVE_DTHETA_CLAMP, MC_DRIVE_DTHETA_CLAMP);
        int32_t b = mc_clamp_i32((dt * d->bemf_mul) >> 8, -d->d_max, d->d_max);
        q += b;
    }
    return mc_clamp_i32(q, -d->d_max, d->d_max);
}

void mc_drive_command(const mc_drive_t *d, int32_t tau, int32_t dtheta_w,
                      int bemf_on, mc_drive_out_t *out)
{
    int32_t q = mc_drive_q16(d, tau, dtheta_w, bemf_on);
    uint32_t mag = (uint32_t)(q < 0 ? -q : q);
    /* mag <= 2^16, top < 2^12: product < 2^28 */
    uint32_t duty = (mag * (uint32_t)d->pwm_top + 32768u) >> 16;
    if (duty > (uint32_t)d->duty_limit)
        duty = (uint32_t)d->duty_limit;
    out->duty = (uint16_t)duty;
    out->dir = (uint8_t)(q >= 0);
    out->enable = 1;
}
