/* Extra plant steppers: Noh-Bathe two-sub-step explicit and a linearly-implicit IMEX Euler (bands + damping implicit). */
#ifndef HE_STEP_MORE_H
#define HE_STEP_MORE_H

#include <stdint.h>
#include "he_plant.h"

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
 *   only within one he_advance call). Stable limit: computed in he_step_more_limit from the 2x2
 *   amplification matrix of the scalar test equation x'' + c x' + w2 x = 0 (see there).
 *   Overdamped (C x' = F, no velocity state): the two-stage explicit Runge-Kutta with its stage at p h,
 *     xp = x0 + p h f0,  x1 = x0 + h ((1 - 1/(2p)) f0 + 1/(2p) fp),  f = F/C  (order 2, limit 2/rate).
 *
 * HE_STEP_IMEX: linearly implicit (Rosenbrock-W) Euler, order 1. The band torques (their tangent
 *   stiffness, a tridiagonal matrix per chain) and the viscous/back-EMF damping are implicit; the
 *   reaction torque, motor voltage and perturbations are explicit:
 *     Kb = -dF_band/dx at x0 (bond slope s_j = tangent stiffness of bond j,j+1; small-angle slope
 *          for the geometric beta form: a W-method, still order 1)
 *     inertia:     (I + h C + h^2 Kb) v1 = I v0 + h F(t, x0),   x1 = x0 + h v1
 *     overdamped:  (C + h Kb) (x1 - x0) = h F(t, x0),           v1 = (x1 - x0)/h
 *   one Thomas solve per chain per step. For the linear lattice without reaction this is backward
 *   Euler (unconditionally stable); the limit comes from the explicit reaction only:
 *     inertia: h < (c + sqrt(c^2 + 4 wr2)) / wr2,  c = C_min/I, wr2 = k_react/I
 *     overdamped: h < 2 C_min / k_react
 *   k_react = Gershgorin bound of the reaction Jacobian (as in he_plant_bounds); INFINITY without
 *   reaction (hil: the firmware's torque is held per tick).
 */
enum { HE_NOH_BATHE_P_PERMILLE = 540 };   /* p = 0.54 */

/* Stable step (s) of the HE_STEP_NOH_BATHE / HE_STEP_IMEX steppers; -1 for another id. */
double he_step_more_limit(const he_plant_t *p, int stepper, int *limiting_chain);
/* Spectral radius of the Noh-Bathe amplification matrix for x'' + c x' + w2 x = 0 at step h. */
double he_noh_bathe_radius(double c, double w2, double h);
/* Set every |x_i|, |v_i| < HE_TINY_RAD to 0 (called after each step by every stepper). A decaying mode
 * reaches the subnormal range (< 2.2e-308) after ~5 s at the beta chain's 133/s damping, and subnormal
 * arithmetic is up to 100x slower on x86: without this, long runs slow down by 2x or more. */
void he_flush_tiny(int n2, double *x, double *v);
#define HE_TINY_RAD 1e-200
/* he_advance for the steppers of this file (same contract as he_advance). */
int he_advance_more(const he_plant_t *p, int stepper, double h, int64_t nsteps, double *t, double *x, double *v);

#endif /* HE_STEP_MORE_H */
