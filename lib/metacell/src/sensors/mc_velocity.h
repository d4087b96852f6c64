/* Windowed-difference velocity estimate of both angles, for back-EMF compensation. */
#ifndef MC_VELOCITY_H
#define MC_VELOCITY_H

#include <stdint.h>
#include "../mc_fixed.h"

/*
 * omega_i[n] = (theta_i[n] - theta_i[n - W]) / (W * dt),  W = 2^log2w ticks, i = alpha, beta.
 * The estimator returns the raw window differences dtheta_i (counts per W ticks);
 * the drive scales them into a voltage with a constant computed once from the
 * control rate (no division per tick). Inputs are the tick's clamped angles
 * (|theta| <= MC_ANGLE_CLAMP), so |dtheta| <= 2*MC_ANGLE_CLAMP = MC_VEL_DIFF_MAX.
 * One ring of the last W positions per angle, with a shared head; after a reset
 * every slot holds the reset angle (velocity 0), never garbage.
 */
#define MC_VEL_RING_LOG2_MAX 8                   /* up to 256 ticks */
#define MC_VEL_RING (1 << MC_VEL_RING_LOG2_MAX)
#define MC_VEL_DIFF_MAX 4096                     /* counts per window */

typedef struct {
    uint16_t head;     /* slot holding theta[n - W] */
    uint16_t mask;     /* W - 1 */
    int32_t ring[MC_VEL_RING][2];   /* [slot][alpha, beta] */
} mc_vel_t;

/* Configuration path: W = 2^log2w (clamped to 0..8), every slot = the angles. */
void mc_vel_reset(mc_vel_t *v, int log2w, int32_t theta_a, int32_t theta_b);
/* Push both angles (clamped to +-MC_ANGLE_CLAMP); out[i] = theta_i[n] - theta_i[n - W]. */
void mc_vel_update(mc_vel_t *v, int32_t theta_a, int32_t theta_b, int32_t out[2]);

#ifndef MC_CDEF
MC_INLINE void mc_vel_update_inl(mc_vel_t *v, int32_t ta, int32_t tb, int32_t *wa, int32_t *wb)
{
    unsigned h = v->head;
    int32_t *slot = v->ring[h];
    *wa = ta - slot[0];
    *wb = tb - slot[1];
    slot[0] = ta;
    slot[1] = tb;
    v->head = (uint16_t)((h + 1u) & v->mask);
}
#endif

#endif /* MC_VELOCITY_H */
