/* Windowed-difference velocity estimate (equation in mc_velocity.h). */
#include "mc_velocity.h"

void mc_vel_reset(mc_vel_t *v, int log2w, int32_t theta_a, int32_t theta_b)
{
    if (log2w < 0)
        log2w = 0;
    if (log2w > MC_VEL_RING_LOG2_MAX)
        log2w = MC_VEL_RING_LOG2_MAX;
    theta_a = mc_clamp_sym(theta_a, MC_ANGLE_CLAMP);
    theta_b = mc_clamp_sym(theta_b, MC_ANGLE_CLAMP);
    v->mask = (uint16_t)((1u << log2w) - 1u);
    v->head = 0;
    for (unsigned i = 0; i <= v->mask; i++) {  /* only the W slots in use are read */
        v->ring[i][0] = theta_a;
        v->ring[i][1] = theta_b;
    }
}

void mc_vel_update(mc_vel_t *v, int32_t theta_a, int32_t theta_b, int32_t out[2])
{
    mc_vel_update_inl(v, mc_clamp_sym(theta_a, MC_ANGLE_CLAMP),
                      mc_clamp_sym(theta_b, MC_ANGLE_CLAMP), &out[0], &out[1]);
}
