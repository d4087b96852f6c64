/* Windowed-difference velocity estimate for back-EMF compensation. */
#ifndef MC_VELOCITY_H
#define MC_VELOCITY_H

#include <stdint.h>

/*
 * omega[n] = (theta[n] - theta[n - W]) / (W * dt),  W = 2^log2w ticks.
 * The estimator returns the raw window difference dtheta (counts per W ticks,
 * clamped to +-MC_VEL_DIFF_CLAMP); the drive scales it into a voltage with a
 * constant computed once from the control rate (no division per tick).
 * The window is a ring of the last W positions; the first W ticks after a reset
 * see the reset position (velocity 0), never garbage.
 */
#define MC_VEL_RING_LOG2_MAX 8                   /* up to 256 ticks */
#define MC_VEL_RING (1 << MC_VEL_RING_LOG2_MAX)
#define MC_VEL_DIFF_CLAMP 1024                   /* counts per window */

typedef struct {
    int32_t ring[MC_VEL_RING];
    uint16_t head;
    uint16_t mask;     /* W - 1 */
} mc_vel_t;

void mc_vel_reset(mc_vel_t *v, int log2w, int32_t theta);
/* Push theta (counts), return clamped difference over the window. */
int32_t mc_vel_update(mc_vel_t *v, int32_t theta);

#endif /* MC_VELOCITY_H */
