/* Noh-Bathe two-sub-step explicit plant stepper (equations in he_noh_bathe.h). */
#include <math.h>
#include <stddef.h>
#include "he_noh_bathe.h"

#define NB_P ((double)HE_NOH_BATHE_P_PERMILLE / 1000.0)

/* 1 if some perturbation switches on or off in (ta, tb] */
static int he_forcing_changes(const he_plant_t *p, double ta, double tb)
{
    for (int i = 0; i < p->npert; i++) {
        const he_pert_t *q = &p->pert[i];
        if ((q->t0 > ta && q->t0 <= tb) || (q->t1 > ta && q->t1 <= tb))
            return 1;
    }
    return 0;
}

static void nb_coef(double *q0, double *q1, double *q2)
{
    double p = NB_P;
    *q1 = (1.0 - 2.0 * p) / (2.0 * p * (1.0 - p));
    *q2 = 0.5 - p * *q1;
    *q0 = -*q1 - *q2 + 0.5;
}

/* one Noh-Bathe step of the scalar test equation x'' = -w2 x - c x' on the carried state (x, v, a):
 * exactly the vector scheme below, where a1 (damping at the predicted velocity) becomes the next a0 */
static void nb_scalar(double c, double w2, double h, double y[3])
{
    double q0, q1, q2, p = NB_P, s = (1.0 - p) * h;
    nb_coef(&q0, &q1, &q2);
    double x = y[0], v = y[1], a0 = y[2];
    double xp = x + p * h * v + 0.5 * p * h * p * h * a0;
    double ap = -w2 * xp - c * (v + p * h * a0);
    double vp = v + 0.5 * p * h * (a0 + ap);
    double x1 = xp + s * vp + 0.5 * s * s * ap;
    double a1 = -w2 * x1 - c * (vp + s * ap);
    y[0] = x1;
    y[1] = vp + s * (q0 * a0 + (0.5 + q1) * ap + q2 * a1);
    y[2] = a1;
}

double he_noh_bathe_radius(double c, double w2, double h)
{
    /* amplification matrix A (3x3) of the scaled state (x, h v, h^2 a), columns = images of the unit
     * states; spectral radius rho = lim ||A^m||^(1/m), estimated with m = 2^40 by repeated squaring
     * (renormalised, the log of the scale kept apart): a transient factor K of the non-normal A
     * biases the estimate by only ln(K)/m */
    double A[3][3], B[3][3], logs = 0.0;
    const double sc[3] = {1.0, h, h * h};
    for (int j = 0; j < 3; j++) {
        double y[3] = {0.0, 0.0, 0.0};
        y[j] = 1.0 / sc[j];
        nb_scalar(c, w2, h, y);
        for (int i = 0; i < 3; i++)
            A[i][j] = y[i] * sc[i];
    }
    double m = 1.0;
    for (int k = 0; k < 40; k++) {
        double nrm = 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                B[i][j] = A[i][0] * A[0][j] + A[i][1] * A[1][j] + A[i][2] * A[2][j];
                nrm = fabs(B[i][j]) > nrm ? fabs(B[i][j]) : nrm;
            }
        logs *= 2.0;
        m *= 2.0;
        if (!(nrm > 0.0) || !isfinite(nrm))
            return nrm > 0.0 ? INFINITY : 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                A[i][j] = B[i][j] / nrm;
        logs += log(nrm);
    }
    return exp(logs / m);
}

/* largest h with radius <= 1 (+ 1e-9) for one (c, w2): geometric scan then bisection */
static double nb_limit_one(double c, double w2)
{
    double scale = sqrt(w2) > c ? sqrt(w2) : c;
    if (!(scale > 0.0))
        return INFINITY;
    double lo = 1e-2 / scale, hi = lo;
    while (he_noh_bathe_radius(c, w2, hi) <= 1.0 + 1e-9) {
        lo = hi;
        hi *= 1.25;
        if (hi > 1e3 / scale)
            return INFINITY;
    }
    for (int it = 0; it < 40; it++) {
        double mid = 0.5 * (lo + hi);
        if (he_noh_bathe_radius(c, w2, mid) <= 1.0 + 1e-9)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

static void nb_accel(const he_plant_t *p, double t, const double *x, const double *v, double *a,
                     double *F, double *C)
{
    int n = p->n, n2 = 2 * n;
    he_plant_forces(p, t, x, F, C);
    for (int i = 0; i < n2; i++)
        a[i] = (F[i] - C[i] * v[i]) / p->I[i >= n];
}

int he_noh_bathe_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                         double *v, double *work)
{
    int n = p->n, n2 = 2 * n;
    double q0, q1, q2, pp = NB_P, s = (1.0 - pp) * h, ph = pp * h;
    double *F = work, *C = work + n2, *a0 = work + 2 * n2, *ap = work + 3 * n2, *a1 = work + 4 * n2;
    double *xp = work + 5 * n2, *vp = work + 6 * n2, *w = work + 7 * n2;
    if (stepper != HE_STEP_NOH_BATHE)
        return HE_ERR_STEPPER;
    nb_coef(&q0, &q1, &q2);
    if (!p->inertia) {
        /* xp = x0 + p h f0;  x1 = x0 + h((1 - 1/(2p)) f0 + 1/(2p) fp) */
        double b2 = 0.5 / pp, b1 = 1.0 - b2;
        for (int64_t k = 0; k < nsteps; k++) {
            double tt = t0 + (double)k * h;
            he_plant_forces(p, tt + HE_STAGE_EDGE * h, x, F, C);
            for (int i = 0; i < n2; i++) {
                a0[i] = F[i] / C[i];
                xp[i] = x[i] + ph * a0[i];
            }
            he_plant_forces(p, tt + ph, xp, F, C);
            for (int i = 0; i < n2; i++) {
                double fp = F[i] / C[i];
                v[i] = b1 * a0[i] + b2 * fp;
                x[i] += h * v[i];
            }
            he_flush_tiny(n2, x, v);
        }
        return HE_OK;
    }
    nb_accel(p, t0 + HE_STAGE_EDGE * h, x, v, a0, F, C);
    for (int64_t k = 0; k < nsteps; k++) {
        double tt = t0 + (double)k * h;
        /* sub-step 1: xp = x0 + p h v0 + (p h)^2/2 a0;  ap = a(xp, v0 + p h a0);  vp = v0 + p h/2 (a0 + ap) */
        for (int i = 0; i < n2; i++) {
            xp[i] = x[i] + ph * v[i] + 0.5 * ph * ph * a0[i];
            w[i] = v[i] + ph * a0[i];
        }
        nb_accel(p, tt + ph, xp, w, ap, F, C);
        for (int i = 0; i < n2; i++) {
            vp[i] = v[i] + 0.5 * ph * (a0[i] + ap[i]);
            /* sub-step 2: x1 = xp + s vp + s^2/2 ap;  a1 = a(x1, vp + s ap) */
            x[i] = xp[i] + s * vp[i] + 0.5 * s * s * ap[i];
            w[i] = vp[i] + s * ap[i];
        }
        /* a1 at the left limit of t + h (HE_STAGE_EDGE); when a perturbation edge sits at t + h the
         * carried a0 of the next step would belong to the old piece: recompute it there */
        nb_accel(p, tt + (1.0 - HE_STAGE_EDGE) * h, x, w, a1, F, C);
        for (int i = 0; i < n2; i++) {
            /* v1 = vp + s (q0 a0 + (1/2 + q1) ap + q2 a1);  the next step starts from a0 = a1 */
            v[i] = vp[i] + s * (q0 * a0[i] + (0.5 + q1) * ap[i] + q2 * a1[i]);
            a0[i] = a1[i];
        }
        he_flush_tiny(n2, x, v);
        if (k + 1 < nsteps && he_forcing_changes(p, tt + (1.0 - HE_STAGE_EDGE) * h, tt + (1.0 + HE_STAGE_EDGE) * h))
            nb_accel(p, tt + (1.0 + HE_STAGE_EDGE) * h, x, w, a0, F, C);
    }
    return HE_OK;
}
/* ---------------------------------------------------------------- stable limit */

double he_noh_bathe_limit(const he_plant_t *p, int stepper, int *limiting_chain)
{
    double w2[2], cmin[2], cmax[2], rate[2], best = INFINITY;
    int arg = -1;
    if (stepper != HE_STEP_NOH_BATHE)
        return -1.0;
    he_plant_bounds(p, w2, cmin, cmax, rate);
    for (int ch = 0; ch < 2; ch++) {
        double h = INFINITY;
        if (!p->inertia) {
            if (rate[ch] > 0.0)
                h = 2.0 / rate[ch];                  /* two-stage RK2: |1 + z + z^2/2| <= 1 */
        } else {
            /* worst case over the modes the bounds allow: stiffness 0..w2, damping cmin..cmax */
            static const double frac[6] = {1.0, 0.5, 0.25, 0.1, 0.01, 0.0};
            for (int a = 0; a < 6; a++)
                for (int b = 0; b < 2; b++) {
                    double hh = nb_limit_one(b ? cmax[ch] : cmin[ch], frac[a] * w2[ch]);
                    h = hh < h ? hh : h;
                }
        }
        if (h < best) {
            best = h;
            arg = ch;
        }
    }
    if (limiting_chain)
        *limiting_chain = arg;
    return best;
}
