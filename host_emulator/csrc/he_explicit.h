/* Explicit one-step plant steppers: explicit Euler, semi-implicit (symplectic) Euler, classical RK4 (equations and limits). */
#ifndef HE_EXPLICIT_H
#define HE_EXPLICIT_H

#include "he_step.h"

/*
 * Steppers (h = step, F, C from he_plant_forces; overdamped systems have v = F/C):
 *   HE_STEP_EULER       explicit Euler.  inertia: x1 = x0 + h v0,  v1 = v0 + h (F0 - C v0)/I
 *                                        overdamped: x1 = x0 + h F0/C
 *   HE_STEP_SYMPLECTIC  semi-implicit (symplectic) Euler, damping implicit:
 *                          v1 = (v0 + h F(t0, x0)/I) / (1 + h C/I),  x1 = x0 + h v1
 *                       overdamped: identical to explicit Euler (no velocity state)
 *   HE_STEP_RK4         classical 4th-order Runge-Kutta on (x, v) or on x.
 *
 * Largest stable step (he_explicit_limit), from he_plant_bounds:
 *   euler, inertia:      min over chains of  c_min / w2  and  2 / c_max
 *   symplectic, inertia: (c + sqrt(c^2 + 4 w2)) / w2 with c = c_min (h^2 w2 < 4 + 2 h c)
 *   rk4, inertia:        2.5 / max(sqrt(w2), c_max)
 *   overdamped:          2 / rate (Euler-type), 2.5 / rate (rk4)
 * Entry points: he_explicit_advance, he_explicit_limit (declared in he_step.h).
 */

#endif /* HE_EXPLICIT_H */
