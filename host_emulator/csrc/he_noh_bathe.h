/* Noh-Bathe two-sub-step explicit plant stepper (HE_STEP_NOH_BATHE): equations and stable limit. */
#ifndef HE_NOH_BATHE_H
#define HE_NOH_BATHE_H

#include "he_step.h"

/*
 * HE_STEP_NOH_BATHE (Noh & Bathe, Computers & Structures 129, 2013), splitting ratio p = 0.54,
 *   q1 = (1 - 2p) / (2p(1 - p)),  q2 = 1/2 - p q1,  q0 = -q1 - q2 + 1/2,
 *   a(t, x, v) = (F(t, x) - C v) / I,  a0 = a(t, x0, v0).
 *   sub-step 1 (t -> t + p h):
 *     xp = x0 + p h v0 + (p h)^2/2 a0
 *     ap = a(t + p h, xp, v0 + p h a0)               (damping at the predicted velocity)
 *     vp = v0 + p h/2 (a0 + ap)
 *   sub-step 2 (t + p h -> t + h), s = (1 - p) h:
 *     x1 = xp + s vp + s^2/2 ap
 *     a1 = a(t + h, x1, vp + s ap)
 *     v1 = vp + s (q0 a0 + (1/2 + q1) ap + q2 a1)
 *   Second order with and without damping; 2 force evaluations per step (a1 is reused as the next a0
 *   only within one he_advance call). Stable limit: computed in he_noh_bathe_limit from the 2x2
 *   amplification matrix of the scalar test equation x'' + c x' + w2 x = 0 (see there).
 *   Overdamped (C x' = F, no velocity state): the two-stage explicit Runge-Kutta with its stage at p h,
 *     xp = x0 + p h f0,  x1 = x0 + h ((1 - 1/(2p)) f0 + 1/(2p) fp),  f = F/C  (order 2, limit 2/rate).
 */
enum { HE_NOH_BATHE_P_PERMILLE = 540 };   /* p = 0.54 */

/* Spectral radius of the Noh-Bathe amplification matrix for x'' + c x' + w2 x = 0 at step h. */
double he_noh_bathe_radius(double c, double w2, double h);
/* Entry points: he_noh_bathe_advance, he_noh_bathe_limit (declared in he_step.h). */

#endif /* HE_NOH_BATHE_H */
