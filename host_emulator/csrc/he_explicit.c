/* Explicit one-step plant steppers: explicit Euler, semi-implicit (symplectic) Euler, RK4 (equations in he_explicit.h). */
#include <math.h>
#include <stddef.h>
#include "he_explicit.h"

double he_explicit_limit(const he_plant_t *p, int stepper, int *limiting_chain)
{
    double w2[2], cmin[2], cmax[2], rate[2], best = INFINITY;
    int arg = -1;
    if (stepper != HE_STEP_EULER && stepper != HE_STEP_SYMPLECTIC && stepper != HE_STEP_RK4)
        return -1.0;
    he_plant_bounds(p, w2, cmin, cmax, rate);
    for (int ch = 0; ch < 2; ch++) {
        double h = INFINITY;
        if (!p->inertia) {
            if (rate[ch] > 0.0)
                h = (stepper == HE_STEP_RK4 ? 2.5 : 2.0) / rate[ch];
        } else if (stepper == HE_STEP_EULER) {
            /* |1 + h lambda| < 1 for lambda = -c/2 +- i sqrt(w2 - c^2/4) */
            double a = w2[ch] > 0.0 ? cmin[ch] / w2[ch] : INFINITY;
            double b = cmax[ch] > 0.0 ? 2.0 / cmax[ch] : INFINITY;
            h = a < b ? a : b;
        } else if (stepper == HE_STEP_SYMPLECTIC) {
            if (w2[ch] > 0.0)
                h = (cmin[ch] + sqrt(cmin[ch] * cmin[ch] + 4.0 * w2[ch])) / w2[ch];
        } else {
            double m = sqrt(w2[ch]) > cmax[ch] ? sqrt(w2[ch]) : cmax[ch];
            if (m > 0.0)
                h = 2.5 / m;
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

/* derivative of the state: dx = v (or F/C), dv = (F - C v)/I */
static void deriv(const he_plant_t *p, double t, const double *x, const double *v,
                  double *dx, double *dv, double *F, double *C)
{
    int n = p->n, n2 = 2 * n;
    he_plant_forces(p, t, x, F, C);
    if (p->inertia) {
        for (int i = 0; i < n2; i++) {
            double I = p->I[i >= n];
            dx[i] = v[i];
            dv[i] = (F[i] - C[i] * v[i]) / I;
        }
    } else {
        for (int i = 0; i < n2; i++) {
            dx[i] = F[i] / C[i];
            dv[i] = 0.0;
        }
    }
}

int he_explicit_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                        double *v, double *work)
{
    int n = p->n, n2 = 2 * n;
    /* work: F, C, then the rk4 stages k1x k1v k2x k2v k3x k3v k4x k4v and the stage state xs vs */
    double *F = work, *C = work + n2;
    double *k1x = work + 2 * n2, *k1v = work + 3 * n2, *k2x = work + 4 * n2, *k2v = work + 5 * n2;
    double *k3x = work + 6 * n2, *k3v = work + 7 * n2, *k4x = work + 8 * n2, *k4v = work + 9 * n2;
    double *xs = work + 10 * n2, *vs = work + 11 * n2;
    for (int64_t s = 0; s < nsteps; s++) {
        double tt = t0 + (double)s * h;   /* no accumulated rounding in t */
        if (stepper == HE_STEP_RK4) {
            deriv(p, tt + HE_STAGE_EDGE * h, x, v, k1x, k1v, F, C);
            for (int i = 0; i < n2; i++) { xs[i] = x[i] + 0.5 * h * k1x[i]; vs[i] = v[i] + 0.5 * h * k1v[i]; }
            deriv(p, tt + 0.5 * h, xs, vs, k2x, k2v, F, C);
            for (int i = 0; i < n2; i++) { xs[i] = x[i] + 0.5 * h * k2x[i]; vs[i] = v[i] + 0.5 * h * k2v[i]; }
            deriv(p, tt + 0.5 * h, xs, vs, k3x, k3v, F, C);
            for (int i = 0; i < n2; i++) { xs[i] = x[i] + h * k3x[i]; vs[i] = v[i] + h * k3v[i]; }
            deriv(p, tt + (1.0 - HE_STAGE_EDGE) * h, xs, vs, k4x, k4v, F, C);
            /* y1 = y0 + h/6 (k1 + 2 k2 + 2 k3 + k4) */
            for (int i = 0; i < n2; i++) {
                x[i] += h / 6.0 * (k1x[i] + 2.0 * k2x[i] + 2.0 * k3x[i] + k4x[i]);
                v[i] += h / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
            }
            if (!p->inertia)
                for (int i = 0; i < n2; i++)
                    v[i] = (k1x[i] + 2.0 * k2x[i] + 2.0 * k3x[i] + k4x[i]) / 6.0;
        } else {
            he_plant_forces(p, tt + HE_STAGE_EDGE * h, x, F, C);
            if (!p->inertia) {
                for (int i = 0; i < n2; i++) {
                    v[i] = F[i] / C[i];           /* x' = F/C */
                    x[i] += h * v[i];
                }
            } else if (stepper == HE_STEP_SYMPLECTIC) {
                for (int i = 0; i < n2; i++) {
                    double I = p->I[i >= n];
                    v[i] = (v[i] + h * F[i] / I) / (1.0 + h * C[i] / I);
                    x[i] += h * v[i];
                }
            } else {
                for (int i = 0; i < n2; i++) {
                    double I = p->I[i >= n];
                    double a = (F[i] - C[i] * v[i]) / I;
                    x[i] += h * v[i];
                    v[i] += h * a;
                }
            }
        }
        he_flush_tiny(n2, x, v);
    }
    return HE_OK;
}
