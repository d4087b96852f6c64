/* Low-lag velocity estimate of both angles (alpha-beta tracking observer), for back-EMF compensation. */
#ifndef MC_VELOCITY_H
#define MC_VELOCITY_H

#include <stdint.h>
#include "../mc_fixed.h"

/*
 * Per angle i (alpha, beta), once per control tick (time enters only as "one tick"):
 *
 *   x[n]  = theta_i[n] * 2^16                  measured angle, counts Q16
 *   pr    = p[n-1] + v[n-1]                     predicted angle, counts Q16
 *   e     = x[n] - pr                           innovation, counts Q16
 *   p[n]  = pr + (e >> 1)                       angle estimate, gain a = 1/2
 *   v[n]  = v[n-1] + (e >> 3)                   velocity state, gain b = 1/8
 *   out   = clamp((v[n] + (e >> 1)) >> 10, -4096, 4095)   velocity, counts/tick Q6
 *
 * p: counts Q16; v: counts per tick Q16 (rad/s = v / 2^16 * (2 pi/400) * f_ctrl);
 * out: counts per tick with MC_VEL_OUT_LOG2 = 6 fraction bits (LSB 0.49 rad/s at
 * 2 kHz), the unit the drive scales into a voltage with its constant m_b (mc_drive.h).
 *
 * Why out is v[n] + a e and not v[n]: in continuous terms the observer is
 * p' = v + a e, v' = b e; v follows the true velocity through b/(s^2 + a s + b)
 * (tens of degrees late at the 34 Hz long-wave oscillation), while v + a e adds the
 * lead of the zero (a s + b), and the extra half tick of lead of v[n] over v[n-1]
 * offsets the hold of the command over the next tick. Measured against the velocity
 * at the middle of that next tick (when the voltage acts), at 2 kHz this passes a
 * 34.5 Hz oscillation with gain 1.08 and 2 degrees of lag (gain 1.00, 0 degrees at
 * 5 Hz); the 16 ms window it replaces lagged by about 100 degrees at 34.5 Hz.
 * Poles: z^2 - 1.375 z + 0.5 = 0, |z| = 0.71 at +-13.5 degrees (settles in ~8 ticks).
 * The price is encoder noise: a one-count step of theta gives out a spike of at most
 * 5/8 count/tick, decaying within a few ticks (0.39 V of compensation on the rig's
 * motors at 2 kHz, 3 mN*m). Shifts only: no multiply, no division per tick.
 *
 * Ranges: |theta| <= MC_ANGLE_CLAMP = 2^11 (the tick's clamped angles), so |x| <= 2^27.
 * The filter is linear and stable; the l1 norms of its impulse responses from x
 * bound, for every input history with |x| <= 2^27 (a reset puts it at rest at the
 * reset angle, i.e. in that set): |v| <= 0.36*2^27, |p| <= 1.25*2^27,
 * |pr| <= 1.49*2^27, |e| <= 2.49*2^27 < 2^29, |v + (e >> 1)| <= 1.34*2^27: nothing
 * wraps, and only the output needs its clamp (+-64 counts/tick: 2000 rad/s at 2 kHz,
 * far above the motors' no-load 450 rad/s), which keeps |out| <= MC_VEL_DIFF_MAX.
 * Right shifts of negative values are arithmetic (GCC and Clang define them so) and
 * round toward minus infinity.
 */
#define MC_VEL_OUT_LOG2 6            /* output: counts/tick with 6 fraction bits */
#define MC_VEL_DIFF_MAX 4096         /* |out| limit, counts/tick Q6 */
#define MC_VEL_SHIFT_P 1             /* a = 1/2 */
#define MC_VEL_SHIFT_V 3             /* b = 1/8 */

typedef struct {
    int32_t p[2];      /* angle estimates, counts Q16 [alpha, beta] */
    int32_t v[2];      /* velocity states, counts/tick Q16 */
} mc_vel_t;

/* Configuration path: estimates = the angles (clamped to +-MC_ANGLE_CLAMP), at rest. */
void mc_vel_reset(mc_vel_t *v, int32_t theta_a, int32_t theta_b);
/* One tick with both angles (clamped to +-MC_ANGLE_CLAMP); out[i] = velocity, counts/tick Q6. */
void mc_vel_update(mc_vel_t *v, int32_t theta_a, int32_t theta_b, int32_t out[2]);

#ifndef MC_CDEF
MC_INLINE int32_t mc_vel_step1(mc_vel_t *o, int i, int32_t theta)
{
    int32_t v = o->v[i];
    int32_t pr = o->p[i] + v;
    int32_t e = (int32_t)((uint32_t)theta << 16) - pr;
    int32_t ea = e >> MC_VEL_SHIFT_P;
    o->p[i] = pr + ea;
    v += e >> MC_VEL_SHIFT_V;
    o->v[i] = v;
    int32_t w = (v + ea) >> (16 - MC_VEL_OUT_LOG2);
    int32_t s = w >> 31;
    if ((w >> 12) != s)              /* outside [-4096, 4095] */
        w = s ^ (MC_VEL_DIFF_MAX - 1);
    return w;
}

MC_INLINE void mc_vel_update_inl(mc_vel_t *o, int32_t ta, int32_t tb, int32_t *wa, int32_t *wb)
{
    *wa = mc_vel_step1(o, 0, ta);
    *wb = mc_vel_step1(o, 1, tb);
}
#endif

#endif /* MC_VELOCITY_H */
