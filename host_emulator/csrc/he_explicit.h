/* Time steppers for the plant (separate from the physics in he_plant.c), selectable by id. */
#ifndef HE_STEP_H
#define HE_STEP_H

#include "he_plant.h"

/*
 * Steppers (h = step, F, C from he_plant_forces; overdamped systems have v = F/C):
 *   HE_STEP_EULER       explicit Euler.  inertia: x1 = x0 + h v0,  v1 = v0 + h (F0 - C v0)/I
 *                                        overdamped: x1 = x0 + h F0/C
 *   HE_STEP_SYMPLECTIC  semi-implicit (symplectic) Euler, damping implicit:
 *                          v1 = (v0 + h F(t0, x0)/I) / (1 + h C/I),  x1 = x0 + h v1
 *                       overdamped: identical to explicit Euler (no velocity state)
 *   HE_STEP_RK4         classical 4th-order Runge-Kutta on (x, v) or on x.
 * To add one: an id here, a function in he_step.c, its limit in he_step_limit,
 * and a line in the Python registry (host_emulator/models/steppers.py).
 */
/* HE_STEP_NOH_BATHE and HE_STEP_IMEX: equations and limits in he_step_more.h */
/* Stages at the ends of a step are evaluated just inside it, at t + e h and t + (1 - e) h with
 * e = HE_STAGE_EDGE: the perturbations are piecewise constant, and with their edges on step
 * boundaries this keeps every step on one side of an edge (otherwise the end stage sees the next
 * piece and a high-order stepper drops to first order at each edge; rounding of t decides which). */
#define HE_STAGE_EDGE 1e-9
enum { HE_STEP_EULER = 0, HE_STEP_SYMPLECTIC = 1, HE_STEP_RK4 = 2, HE_STEP_NOH_BATHE = 3, HE_STEP_IMEX = 4,
       HE_STEP_COUNT = 5 };

/* Largest stable step (s) for this plant and stepper, from he_plant_bounds:
 *   euler, inertia:      min over chains of  c_min / w2  and  2 / c_max
 *   symplectic, inertia: (c + sqrt(c^2 + 4 w2)) / w2 with c = c_min (h^2 w2 < 4 + 2 h c)
 *   rk4, inertia:        2.5 / max(sqrt(w2), c_max)
 *   overdamped:          2 / rate (Euler-type), 2.5 / rate (rk4)
 * Returns a negative value for an unknown stepper, INFINITY when nothing limits. */
double he_step_limit(const he_plant_t *p, int stepper, int *limiting_chain);

/* Advance nsteps steps of size h from *t; x and v hold 2n doubles (v unused when
 * overdamped but still written as F/C). Checks the state once at the end:
 * HE_OK, HE_ERR_NONFINITE, HE_ERR_DIVERGED, HE_ERR_STEPPER, HE_ERR_ARG. */
int he_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double *t, double *x, double *v);

/* HE_OK, or the error code for a non-finite or diverged state (2n entries each). */
int he_state_check(int n2, const double *x, const double *v);

#endif /* HE_STEP_H */
