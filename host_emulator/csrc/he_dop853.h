/* Dormand-Prince 8(5,3) plant stepper (HE_STEP_DOP853): fixed steps through he_advance, and the adaptive driver
 * with PI step control that the lattice model runs (equations, error norm, step control, limits). */
#ifndef HE_DOP853_H
#define HE_DOP853_H

#include <stdint.h>
#include "he_step.h"

/*
 * The explicit Runge-Kutta pair of Dormand & Prince (Hairer, Norsett & Wanner, Solving ODE I, 2nd ed., II.10;
 * the tableau of Hairer's dop853.f, the same digits as scipy's DOP853): 12 stages, order 8, with an embedded
 * 5th-order and 3rd-order error estimate, first-same-as-last (the 13th evaluation, f at the new state, is the
 * next step's first stage), so an accepted step costs 12 force evaluations and a rejected one 11.
 *
 * State y = (x, v), f(t, y) = (v, (F(t, x) - C v) / I) with F, C from he_plant_torques / he_damping (inertia
 * on); y = x, f = F / C (overdamped; v is written as F / C at the end). C is constant over one call.
 * Stages at the ends of a step are evaluated at t + HE_STAGE_EDGE h and t + (1 - HE_STAGE_EDGE) h (he_step.h).
 *
 * Error of a step (Hairer's dop853): with sk_i = atol + rtol max(|y0_i|, |y1_i|) over every state entry i
 * (N of them), e5 = h sum_j E5_j k_j and e3 = h sum_j E3_j k_j,
 *     err = |h| S5 / sqrt(N (S5 + 0.01 S3)),   S5 = sum_i (e5_i / (h sk_i))^2,  S3 likewise with e3,
 * an RMS estimate of order 8 that the 3rd-order part keeps honest where the 5th-order one underestimates.
 * Accepted when err <= 1.
 *
 * PI step control (Gustafsson's, in Hairer's form): after an accepted step
 *     h_new = h clamp(safe err^-(1/8 - 0.2 beta) err_old^beta, 1/3, 6)
 * with err_old = max(err, 1e-4) of the previous accepted step (beta = HE_DOP853_BETA, safe = HE_DOP853_SAFE),
 * and no growth right after a rejection; after a rejected one h_new = h max(safe err^-(1/8 - 0.2 beta), 1/3)
 * (h / 10 when err is not finite). h_new <= h_max always. A step that would end within HE_DOP853_STRETCH steps of the interval's end is
 * stretched or split so that the last steps are equal (no sliver step at an output time or a forcing edge).
 *
 * Switches of the force law (he_plant_switches: a band going slack, psi' changing piece, the actuator clip)
 * make f continuous with a kinked derivative; a step across one has a local error of low order that the
 * embedded estimate misjudges (the max error of a run then comes from a few such steps). So an accepted step
 * whose two ends lie on different sides of some switch is redone up to the switch: its position is found by
 * bisection (HE_DOP853_LOCATE_ITER halvings) on the cubic Hermite interpolant of x over the step, the step is
 * cut to end just before it, and the next step starts there; a switch within HE_DOP853_SWITCH_EPS of either
 * end of the step is left alone. Cost: one discarded attempt per crossing.
 *
 * Fixed steps (he_advance with HE_STEP_DOP853): the 8th-order solution, no error estimate. Largest stable
 * step, from he_plant_bounds: HE_DOP853_LIMIT_X1000 / 1000 / max(sqrt(w2), c_max) per chain (the stability
 * region of the pair holds the left half-disc of radius 5.96: the imaginary axis to 5.96, the real axis to
 * -6.39); overdamped: 6.0 / rate.
 */
#define HE_DOP853_BETA 0.04
#define HE_DOP853_SAFE 0.9
#define HE_DOP853_STRETCH 1.05
#define HE_DOP853_SWITCH_EPS 1e-3
enum { HE_DOP853_LOCATE_ITER = 30 };
enum { HE_DOP853_LIMIT_X1000 = 5200 };   /* 5.2: 87 % of the half-disc radius, as rk4's 2.5 of 2.83 */

/* Scratch of the fixed-step path (per state entry; he_step.h HE_WORK_PER_STATE covers it) and of the
 * adaptive driver (he_dop853_t.work). */
#define HE_DOP853_WORK_PER_STATE 39

/*
 * Adaptive driver state: set the tolerances and the scratch with he_dop853_init, then call he_dop853_run /
 * he_dop853_sampled on one plant; the step size, the PI memory and the first-same-as-last derivative carry
 * from one call to the next (the derivative only when the call starts where the last one ended, on the same
 * state and the same side of every perturbation edge).
 */
typedef struct {
    double rtol, atol;   /* per-step error tolerance (rad, rad/s; see the norm above) */
    double h_max;        /* largest step, s (INFINITY: none) */
    double h_min;        /* smallest step: a step control that needs less fails with HE_ERR_TOL, s */
    double h;            /* the step to try next, s (0: the driver picks one from f and the tolerance) */
    double err_old;      /* PI memory */
    double t_end;        /* end of the last call, s */
    double t_fsal;       /* time at which the stored derivative was evaluated, s */
    int32_t fsal;        /* 1: the scratch holds f at the state and time the last call ended with */
    int32_t rejected;    /* the last attempt was rejected */
    int32_t land;        /* 1 (he_dop853_init's default): redo steps that cross a switch of the force law up to it */
    int64_t steps;       /* accepted steps (all calls) */
    int64_t rejects;     /* rejected steps (all calls) */
    int64_t nfev;        /* force evaluations (all calls) */
    int64_t landings;    /* steps redone to end on a switch of the force law (all calls) */
    double *work;        /* HE_DOP853_WORK_PER_STATE * 2n doubles, owned by the caller */
    int64_t work_len;    /* doubles at work */
} he_dop853_t;

/* Tolerances (rtol >= 0, atol > 0, finite), h_max > 0 (INFINITY allowed) and the scratch; resets the step
 * control and the counters. HE_OK or HE_ERR_ARG. */
int he_dop853_init(he_dop853_t *a, double rtol, double atol, double h_max, double *work, int64_t work_len);
/* Integrate from t0 to t1 > t0 (exactly: the last step ends on t1) in place on x, v (2n each). The forcing must
 * not change inside (t0, t1) (no perturbation edge: he_dop853_sampled cuts there). Checks the state at the end
 * as he_advance does. HE_OK, HE_ERR_ARG, HE_ERR_NOMEM (scratch too short), HE_ERR_TOL (the step control needed
 * a step below h_min: the tolerance cannot be met there), HE_ERR_NONFINITE, HE_ERR_DIVERGED, HE_ERR_BAND. On an
 * error *t_fail (if not NULL) is the time reached. */
int he_dop853_run(const he_plant_t *p, he_dop853_t *a, double t0, double t1, double *x, double *v,
                  double *t_fail);
/* As he_advance_sampled (he_sample.h) with the adaptive driver instead of fixed steps: samples k0+1 .. k0+nsamp
 * at k dt_out, each interval cut at every perturbation edge inside it. *t, *done and the return value as
 * there. */
int he_dop853_sampled(const he_plant_t *p, he_dop853_t *a, double dt_out, int64_t k0, int64_t nsamp, double *t,
                      double *x, double *v, double *out, int64_t *done);

/* Entry points of the fixed-step path: he_dop853_advance, he_dop853_limit (declared in he_step.h). */

#endif /* HE_DOP853_H */
