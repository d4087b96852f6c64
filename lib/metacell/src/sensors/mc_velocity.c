/* Low-lag velocity observer (equations, formats and ranges in mc_velocity.h). */
#include "mc_velocity.h"

void mc_vel_reset(mc_vel_t *v, int32_t theta_a, int32_t theta_b)
{
    theta_a = mc_clamp_sym(theta_a, MC_ANGLE_CLAMP);
    theta_b = mc_clamp_sym(theta_b, MC_ANGLE_CLAMP);
    v->p[0] = (int32_t)((uint32_t)theta_a << 16);
    v->p[1] = (int32_t)((uint32_t)theta_b << 16);
    v->v[0] = v->v[1] = 0;
}

void mc_vel_update(mc_vel_t *v, int32_t theta_a, int32_t theta_b, int32_t out[2])
{
    mc_vel_update_inl(v, mc_clamp_sym(theta_a, MC_ANGLE_CLAMP),
                      mc_clamp_sym(theta_b, MC_ANGLE_CLAMP), &out[0], &out[1]);
}
