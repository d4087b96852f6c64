/* Time steppers for the plant (physics in he_plant.c): ids, the common entry points and the per-method contract. */
#ifndef HE_STEP_H
#define HE_STEP_H

#include <stdint.h>
#include "he_plant.h"

/*
 * One stepper per id, each in its own file with its equations and stable limit beside the code:
 *   HE_STEP_EULER, HE_STEP_SYMPLECTIC, HE_STEP_RK4   he_explicit.{h,c}   (explicit one-step methods)
 *   HE_STEP_NOH_BATHE                                he_noh_bathe.{h,c}  (two-sub-step explicit)
 *   HE_STEP_IMEX                                     he_imex.{h,c}       (linearly implicit Euler)
 *   HE_STEP_DOP853                                   he_dop853.{h,c}     (Dormand-Prince 8(5,3); fixed steps
 *                                                                         here, adaptive through its driver)
 * he_step.c dispatches by id and does what every method shares (scratch, final state check).
 * To add one: an id here, a file with its <name>_advance and <name>_limit (the contract below), a case in
 * he_step.c's two switches, and a line in the Python registry (host_emulator/models/steppers.py).
 */
enum { HE_STEP_EULER = 0, HE_STEP_SYMPLECTIC = 1, HE_STEP_RK4 = 2, HE_STEP_NOH_BATHE = 3, HE_STEP_IMEX = 4,
       HE_STEP_DOP853 = 5, HE_STEP_COUNT = 6 };

/* Stages at the ends of a step are evaluated just inside it, at t + e h and t + (1 - e) h with
 * e = HE_STAGE_EDGE: the perturbations are piecewise constant, and with their edges on step
 * boundaries this keeps every step on one side of an edge (otherwise the end stage sees the next
 * piece and a high-order stepper drops to first order at each edge; rounding of t decides which). */
#define HE_STAGE_EDGE 1e-9

/* Scratch a stepper may use: HE_WORK_PER_STATE * 2n doubles (dop853 needs the most, HE_DOP853_WORK_PER_STATE:
 * 13 stages of x and v, the state, a stage state and the new state, F, C, C/I, 1/I and the switch sides). Taken from he_plant_t.work when it is large
 * enough, else malloc'd per he_advance call (HE_ERR_NOMEM if that fails). No stepper keeps a stack array sized
 * by the cell count. */
#define HE_WORK_PER_STATE 39

/* Largest stable step (s) for this plant and stepper, from he_plant_bounds (the formula of each method is
 * in its header). Returns a negative value for an unknown stepper, INFINITY when nothing limits. */
double he_step_limit(const he_plant_t *p, int stepper, int *limiting_chain);

/* Advance nsteps steps of size h from *t; x and v hold 2n doubles (v unused when
 * overdamped but still written as F/C). Checks the state once at the end:
 * HE_OK, HE_ERR_NONFINITE, HE_ERR_DIVERGED, HE_ERR_BAND, HE_ERR_STEPPER, HE_ERR_ARG, HE_ERR_NOMEM. */
int he_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double *t, double *x, double *v);

/* HE_OK, or the error code for a non-finite or diverged state (2n entries each). */
int he_state_check(int n2, const double *x, const double *v);

/* Set every |x_i|, |v_i| < HE_TINY_RAD to 0 (called after each step by every stepper). A decaying mode
 * reaches the subnormal range (< 2.2e-308) after ~5 s at the beta chain's 133/s damping, and subnormal
 * arithmetic is up to 100x slower on x86: without this, long runs slow down by 2x or more. */
void he_flush_tiny(int n2, double *x, double *v);
#define HE_TINY_RAD 1e-200

/*
 * Per-method contract (called by he_step.c only, after it checked n, h, nsteps and the id):
 *   int <method>_advance(p, stepper, h, nsteps, t0, x, v, work): nsteps steps from t0 in place on x, v,
 *       using work (HE_WORK_PER_STATE * 2n doubles); HE_OK or an error code (state check not included).
 *   double <method>_limit(p, stepper, limiting_chain): as he_step_limit, for the method's own ids.
 */
int he_explicit_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                        double *v, double *work);
double he_explicit_limit(const he_plant_t *p, int stepper, int *limiting_chain);
int he_noh_bathe_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                         double *v, double *work);
double he_noh_bathe_limit(const he_plant_t *p, int stepper, int *limiting_chain);
int he_imex_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                    double *v, double *work);
double he_imex_limit(const he_plant_t *p, int stepper, int *limiting_chain);
int he_dop853_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                      double *v, double *work);
double he_dop853_limit(const he_plant_t *p, int stepper, int *limiting_chain);

#endif /* HE_STEP_H */
