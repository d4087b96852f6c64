/* Linearly implicit IMEX Euler plant stepper: bands + damping implicit, reaction explicit (equations in he_imex.h). */
#include <math.h>
#include <stddef.h>
#include "he_imex.h"

/* Solve the tridiagonal system (diag d, symmetric off-diagonal e[j] between j and j+1) in place
 * on r (Thomas algorithm; d is overwritten). Returns 0, or -1 on a non-positive pivot. */
static int thomas(int n, double *d, const double *e, double *r)
{
    for (int j = 1; j < n; j++) {
        if (!(d[j - 1] > 0.0))
            return -1;
        double m = e[j - 1] / d[j - 1];
        d[j] -= m * e[j - 1];
        r[j] -= m * r[j - 1];
    }
    if (!(d[n - 1] > 0.0))
        return -1;
    r[n - 1] /= d[n - 1];
    for (int j = n - 2; j >= 0; j--)
        r[j] = (r[j] - e[j] * r[j + 1]) / d[j];
    return 0;
}

int he_imex_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                    double *v, double *work)
{
    int n = p->n, n2 = 2 * n;
    double *F = work, *C = work + n2, *d = work + 2 * n2, *e = work + 2 * n2 + n, *r = work + 3 * n2;
    if (stepper != HE_STEP_IMEX)
        return HE_ERR_STEPPER;
    for (int64_t k = 0; k < nsteps; k++) {
        double tt = t0 + (double)k * h;
        he_plant_forces(p, tt + HE_STAGE_EDGE * h, x, F, C);
        for (int ch = 0; ch < 2; ch++) {
            const double *xc = x + ch * n;
            double *vc = v + ch * n;
            double I = p->I[ch];
            for (int j = 0; j < n; j++) {
                int i = ch * n + j;
                if (p->inertia) {
                    d[j] = I + h * C[i];                 /* I + h C */
                    r[j] = I * vc[j] + h * F[i];         /* I v0 + h F */
                } else {
                    d[j] = C[i];                         /* C */
                    r[j] = h * F[i];                     /* h F  (unknown: x1 - x0) */
                }
            }
            double w = p->inertia ? h * h : h;           /* + h^2 Kb  or  + h Kb */
            for (int j = 0; j + 1 < n; j++) {
                double sl = w * he_bond_slope(p, ch, j, xc[j] - xc[j + 1]);
                d[j] += sl;
                d[j + 1] += sl;
                e[j] = -sl;
            }
            if (thomas(n, d, e, r) != 0)
                return HE_ERR_ARG;
            for (int j = 0; j < n; j++)
                vc[j] = p->inertia ? r[j] : r[j] / h;    /* v1 */
        }
        for (int i = 0; i < n2; i++)
            x[i] += h * v[i];                            /* x1 = x0 + h v1 */
        he_flush_tiny(n2, x, v);
    }
    return HE_OK;
}

/* ---------------------------------------------------------------- stable limit */

double he_imex_limit(const he_plant_t *p, int stepper, int *limiting_chain)
{
    double w2[2], cmin[2], cmax[2], rate[2], best = INFINITY;
    int arg = -1;
    if (stepper != HE_STEP_IMEX)
        return -1.0;
    he_plant_bounds(p, w2, cmin, cmax, rate);
    for (int ch = 0; ch < 2; ch++) {
        double h = INFINITY;
        double kr = he_react_stiffness(p, ch);
        /* cmin: C_min (overdamped) or C_min / I (inertia), from he_plant_bounds */
        if (kr > 0.0) {
            if (!p->inertia) {
                h = 2.0 * cmin[ch] / kr;             /* explicit Euler on the reaction */
            } else {
                double c = cmin[ch], wr2 = kr / p->I[ch];
                h = (c + sqrt(c * c + 4.0 * wr2)) / wr2;
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
