/* Windowed-difference velocity estimate (equation in mc_velocity.h). */
#include "mc_velocity.h"
#include "../mc_fixed.h"

void mc_vel_reset(mc_vel_t *v, int log2w, int32_t theta)
{
    if (log2w < 0)
        log2w = 0;
    if (log2w > MC_VEL_RING_LOG2_MAX)
        log2w = MC_VEL_RING_LOG2_MAX;
    v->mask = (uint16_t)((1u << log2w) - 1u);
    v->head = 0;
    for (int i = 0; i < MC_VEL_RING; i++)
        v->ring[i] = theta;
}

int32_t mc_vel_update(mc_vel_t *v, int32_t theta)
{
    /* ring[head] holds theta[n - W]; angles are clamped by the caller to
     * +-MC_ANGLE_CLAMP so the difference cannot overflow. */
    int32_t old = v->ring[v->head];
    v->ring[v->head] = theta;
    v->head = (uint16_t)((v->head + 1u) & v->mask);
    return mc_clamp_i32(theta - old, -MC_VEL_DIFF_CLAMP, MC_VEL_DIFF_CLAMP);
}
