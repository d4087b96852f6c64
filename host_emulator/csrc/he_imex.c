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

/* y = W u for W = diag(d) + w K, K the bond Laplacian with slopes sl[b] (bond b = bonds[2b], bonds[2b+1]) */
static void w_apply(const he_plant_t *p, const double *d, const double *sl, const double *u, double *y)
{
    const int32_t *bd = p->bonds;
    for (int j = 0; j < p->n; j++)
        y[j] = d[j] * u[j];
    for (int b = 0; b < p->nbond; b++) {
        int i = bd[2 * b], k = bd[2 * b + 1];
        double f = sl[b] * (u[i] - u[k]);
        y[i] += f;
        y[k] -= f;
    }
}

/* Solve W u = r in place on r (W = diag(d) + w K of w_apply, symmetric; d already holds the diagonal without
 * the bonds) by conjugate gradients preconditioned with W's diagonal (Jacobi), from the Jacobi guess, until the
 * true-recurrence residual |r - W u|_2 <= HE_IMEX_CG_RTOL |r|_2, at most HE_IMEX_CG_MAXIT(n) iterations.
 * Scratch s: 5n doubles. 0, or -1 if it did not converge (or W is not positive definite on the way). */
static int cg_solve(const he_plant_t *p, const double *d, const double *sl, double *r, double *s)
{
    const int n = p->n;
    double *u = s, *res = s + n, *z = s + 2 * n, *q = s + 3 * n, *Mi = s + 4 * n;
    const int32_t *bd = p->bonds;
    for (int j = 0; j < n; j++)
        Mi[j] = d[j];
    for (int b = 0; b < p->nbond; b++) {
        Mi[bd[2 * b]] += sl[b];
        Mi[bd[2 * b + 1]] += sl[b];
    }
    double bb = 0.0;
    for (int j = 0; j < n; j++) {
        if (!(Mi[j] > 0.0))
            return -1;
        Mi[j] = 1.0 / Mi[j];
        bb += r[j] * r[j];
        u[j] = r[j] * Mi[j];
    }
    if (bb == 0.0) {
        return 0;   /* r = 0: u = 0 (r already is) */
    }
    double tol2 = HE_IMEX_CG_RTOL * HE_IMEX_CG_RTOL * bb;
    w_apply(p, d, sl, u, q);
    double rz = 0.0, rr = 0.0;
    for (int j = 0; j < n; j++) {
        res[j] = r[j] - q[j];
        z[j] = res[j] * Mi[j];
        rz += res[j] * z[j];
        rr += res[j] * res[j];
    }
    double *dir = r;   /* r's storage holds the search direction; the solution is copied back at the end */
    for (int j = 0; j < n; j++)
        dir[j] = z[j];
    for (int it = 0; rr > tol2; it++) {
        if (it >= HE_IMEX_CG_MAXIT(n) || !isfinite(rr))
            return -1;
        w_apply(p, d, sl, dir, q);
        double pq = 0.0;
        for (int j = 0; j < n; j++)
            pq += dir[j] * q[j];
        if (!(pq > 0.0))
            return -1;
        double a = rz / pq, rz1 = 0.0;
        rr = 0.0;
        for (int j = 0; j < n; j++) {
            u[j] += a * dir[j];
            res[j] -= a * q[j];
            z[j] = res[j] * Mi[j];
            rz1 += res[j] * z[j];
            rr += res[j] * res[j];
        }
        double beta = rz1 / rz;
        rz = rz1;
        for (int j = 0; j < n; j++)
            dir[j] = z[j] + beta * dir[j];
    }
    for (int j = 0; j < n; j++)
        r[j] = u[j];
    return 0;
}

int he_imex_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                    double *v, double *work)
{
    int n = p->n, n2 = 2 * n;
    double *F = work, *C = work + n2, *d = work + 2 * n2, *e = work + 2 * n2 + n, *r = work + 3 * n2;
    /* an edge list: bond slopes [nbond <= 3n] and the solver's 5n after r */
    double *sl = work + 3 * n2 + n, *cg = sl + HE_MAX_BONDS_PER_CELL * n;
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
            if (p->bonds) {
                for (int b = 0; b < p->nbond; b++)
                    sl[b] = w * he_bond_slope(p, ch, b, xc[p->bonds[2 * b]] - xc[p->bonds[2 * b + 1]]);
                if (cg_solve(p, d, sl, r, cg) != 0)
                    return HE_ERR_SOLVE;
            } else {
                for (int j = 0; j + 1 < n; j++) {
                    double sl = w * he_bond_slope(p, ch, j, xc[j] - xc[j + 1]);
                    d[j] += sl;
                    d[j + 1] += sl;
                    e[j] = -sl;
                }
                if (thomas(n, d, e, r) != 0)
                    return HE_ERR_ARG;
            }
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
