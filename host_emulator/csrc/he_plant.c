/* Plant physics of the emulated lattice: torques, their slopes and bounds (equations beside the code; steppers in he_step.c). */
#include <math.h>
#include <stdlib.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include "he_band.h"
#include "he_plant.h"

/* f(d) and f'(d) of the cubic band law; Python: physics.band_force / physics.band_slope */
double he_cubic(const double c[4], double d) { return c[0] + d * (c[1] + d * (c[2] + d * c[3])); }
double he_cubic_slope(const double c[4], double d) { return c[1] + d * (2.0 * c[2] + d * 3.0 * c[3]); }

double he_damping(const he_plant_t *p, int ch, int j) { return p->eta[ch][j] + p->mgain[ch][j] / p->speed_const; }

/* Band force with the slack rule: g(d) = f(d) for d > 0, else f(0) (slack_f0) or 0. */
static double band_force(const he_plant_t *p, int ch, double d)
{
    if (d > 0.0)
        return he_cubic(p->coef[ch], d);
    return p->slack_f0 ? p->coef[ch][0] : 0.0;
}

int he_plant_nbond(const he_plant_t *p) { return p->bonds ? p->nbond : p->n - 1; }

int he_plant_check(const he_plant_t *p)
{
    if (!p || p->n < 1 || p->n > HE_MAX_CELLS || p->npert < 0 || p->npert > HE_MAX_PERT)
        return HE_ERR_ARG;
    if (p->bands != HE_BANDS_LINEAR && p->bands != HE_BANDS_CUBIC)
        return HE_ERR_ARG;
    if (p->beta_geometry != HE_BETA_SMALL && p->beta_geometry != HE_BETA_GEOMETRIC)
        return HE_ERR_ARG;
    if (p->reaction != HE_REACT_NONE && p->reaction != HE_REACT_IDEAL)
        return HE_ERR_ARG;
    if (!p->eta[0] || !p->eta[1] || !p->kscale[0] || !p->kscale[1] || !p->mgain[0] || !p->mgain[1] ||
        !p->volt[0] || !p->volt[1])
        return HE_ERR_ARG;
    if (p->bonds) {
        if (p->nbond < 0 || p->nbond > HE_MAX_BONDS_PER_CELL * p->n)
            return HE_ERR_ARG;
        for (int b = 0; b < p->nbond; b++) {
            int32_t i = p->bonds[2 * b], k = p->bonds[2 * b + 1];
            if (i < 0 || i >= p->n || k < 0 || k >= p->n || i == k)
                return HE_ERR_ARG;
        }
    }
    int nks = p->bonds ? p->nbond : p->n;   /* the open chain's rows hold n factors, the last unused */
    for (int ch = 0; ch < 2; ch++) {
        if (p->inertia && !(p->I[ch] > 0.0 && isfinite(p->I[ch])))
            return HE_ERR_ARG;
        if (!(p->lever[ch] > 0.0) || !isfinite(p->k_lin[ch]) || !isfinite(p->delta0[ch]))
            return HE_ERR_ARG;
        for (int j = 0; j < p->n; j++) {
            double c = he_damping(p, ch, j);
            if (!isfinite(p->eta[ch][j]) || p->eta[ch][j] < 0.0 || !isfinite(p->mgain[ch][j]) ||
                !isfinite(p->volt[ch][j]))
                return HE_ERR_ARG;
            if (!p->inertia && !(c > 0.0))
                return HE_ERR_ARG;   /* overdamped needs damping on every cylinder */
        }
        for (int b = 0; b < nks; b++)
            if (!isfinite(p->kscale[ch][b]))
                return HE_ERR_ARG;
    }
    if (!(p->lattice_m > 0.0) || !(p->speed_const > 0.0) || !isfinite(p->band_scale) || !(p->react_limit > 0.0))
        return HE_ERR_ARG;
    if (p->react_cell)
        for (int i = 0; i < HE_RC_COUNT * p->n; i++)
            if (!isfinite(p->react_cell[i]))
                return HE_ERR_ARG;
    for (int i = 0; i < p->npert; i++)
        if (p->pert[i].cell < 0 || p->pert[i].cell >= p->n || p->pert[i].chain < 0 ||
            p->pert[i].chain > 1 || !isfinite(p->pert[i].torque))
            return HE_ERR_ARG;
    return HE_OK;
}

double he_band_torque(const he_plant_t *p, int ch, int bond, double xs, double xo)
{
    double ks = p->kscale[ch][bond];
    if (p->bands == HE_BANDS_LINEAR)
        return ks * p->k_lin[ch] * (xs - xo);           /* tau = k*(x_j - x_nb) */
    double L = p->lever[ch], d0 = p->delta0[ch];
    if (ch == 0 || p->beta_geometry == HE_BETA_SMALL) {
        /* delta+- = delta0 +- L*(x_j - x_nb);  tau = s*L*[g(delta+) - g(delta-)] */
        double u = L * (xs - xo);
        return ks * p->band_scale * L * (band_force(p, ch, d0 + u) - band_force(p, ch, d0 - u));
    }
    /* full geometric beta (docs/physics.md#band-torque), a = lattice, L = 2r:
     *   ds = sin b_j - sin b_nb, dc = cos b_j - cos b_nb
     *   Delta+- = sqrt((a +- L ds)^2 + (L dc)^2) - a,  delta+- = delta0 + Delta+-
     *   fT+- = g(delta+-) * (cos b_j (a +- L ds) -+ L sin b_j dc) / (a + Delta+-)
     *   tau  = s*L*(fT+ - fT-) */
    double a = p->lattice_m;
    double sj = sin(xs), cj = cos(xs);
    double ds = sj - sin(xo), dc = cj - cos(xo);
    double xp = a + L * ds, xm = a - L * ds, yy = L * dc;
    double lp = sqrt(xp * xp + yy * yy), lm = sqrt(xm * xm + yy * yy);   /* a + Delta+- (he_plant_switches too) */
    double fp = band_force(p, ch, d0 + (lp - a)) * (cj * xp - L * sj * dc) / lp;
    double fm = band_force(p, ch, d0 + (lm - a)) * (cj * xm + L * sj * dc) / lm;
    return ks * p->band_scale * L * (fp - fm);
}

/* he_plant_range_check on an edge list (out of line: the open chain's check keeps its size) */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static int edges_range_check(const he_plant_t *p, const double *x, int *where)
{
    const int32_t *bd = p->bonds;
    for (int ch = 0; ch < 2; ch++) {
        double lim = HE_BAND_STOP_FACTOR * p->delta_max[ch];
        const double *xc = x + ch * p->n;
        for (int b = 0; b < p->nbond; b++) {
            /* the longer band of the pair: delta0 + L*|x_i - x_k| (small-angle measure), as on the chain */
            if (p->delta0[ch] + p->lever[ch] * fabs(xc[bd[2 * b]] - xc[bd[2 * b + 1]]) > lim) {
                if (where)
                    *where = b + ch * p->nbond;
                return HE_ERR_BAND;
            }
        }
    }
    return HE_OK;
}

int he_plant_range_check(const he_plant_t *p, const double *x, int *where)
{
    if (p->bands != HE_BANDS_CUBIC)
        return HE_OK;
    if (p->bonds)
        return edges_range_check(p, x, where);
    for (int ch = 0; ch < 2; ch++) {
        double lim = HE_BAND_STOP_FACTOR * p->delta_max[ch];
        const double *xc = x + ch * p->n;
        for (int j = 0; j + 1 < p->n; j++) {
            /* the longer band of the pair: delta0 + L*|x_j - x_j+1| (small-angle measure) */
            if (p->delta0[ch] + p->lever[ch] * fabs(xc[j] - xc[j + 1]) > lim) {
                if (where)
                    *where = j + ch * p->n;
                return HE_ERR_BAND;
            }
        }
    }
    return HE_OK;
}

/* tangent stiffness of bond j of chain ch: d tau / d(x_i - x_k) over its cells i, k (small-angle form) */
double he_bond_slope(const he_plant_t *p, int ch, int j, double dx)
{
    double ks = p->kscale[ch][j];
    if (p->bands == HE_BANDS_LINEAR)
        return ks * p->k_lin[ch];
    /* tau = s L [g(d0 + L dx) - g(d0 - L dx)]  =>  dtau/ddx = s L^2 [g'(d0 + L dx) + g'(d0 - L dx)],
     * g' = f' where the band is taut, 0 where slack */
    double L = p->lever[ch], d0 = p->delta0[ch], u = L * dx;
    double gp = d0 + u > 0.0 ? he_cubic_slope(p->coef[ch], d0 + u) : 0.0;
    double gm = d0 - u > 0.0 ? he_cubic_slope(p->coef[ch], d0 - u) : 0.0;
    return ks * p->band_scale * L * L * (gp + gm);
}

/* The reaction law; Python: physics.reaction (+ physics.reaction_jacobian beside it); firmware: mc_reaction.h */
void he_reaction(const he_plant_t *p, double al, double be, double *ra, double *rb)
{
    /* psi'(x) = sign(x) * max(k2|x|, k1|x| - k1 a*)  (= the tri-linear law for k1 > k2) */
    double ax = fabs(al);
    double in = p->k2 * ax, out = p->k1 * ax - p->k1 * p->astar;
    double psi = in > out ? in : out;
    if (al < 0.0)
        psi = -psi;
    *ra = p->k_ab * (be - al) - psi - p->sigma * be;  /* R_a = k_ab(b - a) - psi'(a) - sigma b */
    *rb = p->k_ab * (al - be);                        /* R_b = k_ab(a - b) */
}

/* psi' and R of one cell from its parameters: he_reaction's operations */
static inline void reaction_law(double kab, double sig, double k1, double k2, double ast, double al, double be,
                                double *ra, double *rb)
{
    double ax = fabs(al);
    double in = k2 * ax, out = k1 * ax - k1 * ast;
    double psi = in > out ? in : out;
    if (al < 0.0)
        psi = -psi;
    *ra = kab * (be - al) - psi - sig * be;
    *rb = kab * (al - be);
}

void he_reaction_cell(const he_plant_t *p, int j, double al, double be, double *ra, double *rb)
{
    const double *c = p->react_cell;
    if (!c) {
        he_reaction(p, al, be, ra, rb);
        return;
    }
    int n = p->n;
    reaction_law(c[HE_RC_K_AB * n + j], c[HE_RC_SIGMA * n + j], c[HE_RC_K1 * n + j], c[HE_RC_K2 * n + j],
                 c[HE_RC_ASTAR * n + j], al, be, ra, rb);
}

static double react_rows(double kab, double sig, double k1, double k2, int ch)
{
    double e1 = fabs(kab + k1), e2 = fabs(kab + k2);
    return ch == 0 ? (e1 > e2 ? e1 : e2) + fabs(kab - sig) : 2.0 * fabs(kab);
}

/* Gershgorin rows of dR/dx (psi'' is k1 or k2), the largest over the cells; Python: physics.reaction_gershgorin */
double he_react_stiffness(const he_plant_t *p, int ch)
{
    if (p->reaction != HE_REACT_IDEAL)
        return 0.0;
    if (!p->react_cell)
        return react_rows(p->k_ab, p->sigma, p->k1, p->k2, ch);
    const double *c = p->react_cell;
    int n = p->n;
    double m = 0.0;
    for (int j = 0; j < n; j++) {
        double r = react_rows(c[HE_RC_K_AB * n + j], c[HE_RC_SIGMA * n + j], c[HE_RC_K1 * n + j],
                              c[HE_RC_K2 * n + j], ch);
        m = r > m ? r : m;
    }
    return m;
}

void he_plant_forces(const he_plant_t *p, double t, const double *x, double *F, double *C)
{
    const int n = p->n;
    const double S = p->speed_const;
    for (int ch = 0; ch < 2; ch++) {
        /* he_damping's eta + m / S_L, the rows' addresses read once (a store to C could alias them otherwise) */
        const double *eta = p->eta[ch], *mg = p->mgain[ch];
        double *Cc = C + ch * n;
        for (int j = 0; j < n; j++)
            Cc[j] = eta[j] + mg[j] / S;                           /* eta + Kt/S_L */
    }
    he_plant_torques(p, t, x, F);
}

/* Reciprocal bonds of one chain with cubic small-angle bands: he_band_torque's operations,
 *   T_j = ((ks_j * band_scale) * L) * (g(d0 + u) - g(d0 - u)),  u = L (x_j - x_j+1),
 * then Fc[j] -= T_j, Fc[j+1] += T_j in bond order, as the general loop below does. The torques of a block of
 * bonds first, two per SSE2 instruction where there is SSE2 (each lane the scalar IEEE operations), so the
 * forces keep every bit. */
#if defined(__GNUC__)
__attribute__((always_inline))   /* the open chain's kernel stays inlined where it was (he_plant_torques) */
#endif
static inline void cubic_bonds(const he_plant_t *p, int ch, const double *restrict xc, double *restrict Fc)
{
    enum { BLK = 64 };
    double T[BLK];
    const int n = p->n;
    const double L = p->lever[ch], bs = p->band_scale;
    const he_band_law_t law = he_band_law(p, ch);
    const double *ks = p->kscale[ch];
#ifdef __SSE2__
    const he_band_law2_t law2 = he_band_law2(&law);
    const __m128d Lv = _mm_set1_pd(L), bsv = _mm_set1_pd(bs);
#endif
    for (int j0 = 0; j0 + 1 < n; j0 += BLK) {
        int m = n - 1 - j0 < BLK ? n - 1 - j0 : BLK, i = 0;
        const double *xb = xc + j0, *kb = ks + j0;
#ifdef __SSE2__
        for (; i + 2 <= m; i += 2) {
            __m128d u = _mm_mul_pd(Lv, _mm_sub_pd(_mm_loadu_pd(xb + i), _mm_loadu_pd(xb + i + 1)));
            __m128d kbl = _mm_mul_pd(_mm_mul_pd(_mm_loadu_pd(kb + i), bsv), Lv);
            _mm_storeu_pd(T + i, _mm_mul_pd(kbl, he_band_diff2(&law2, u)));
        }
#endif
        for (; i < m; i++)
            T[i] = kb[i] * bs * L * he_band_diff(&law, L * (xb[i] - xb[i + 1]));
        for (i = 0; i < m; i++) {
            Fc[j0 + i] -= T[i];
            Fc[j0 + i + 1] += T[i];
        }
    }
}

/* The bonds of an edge list with cubic small-angle bands: cubic_bonds' operations on each bond b = (i, k),
 *   T_b = ((ks_b * band_scale) * L) * (g(d0 + u) - g(d0 - u)),  u = L (x_i - x_k),
 * then Fc[i] -= T_b, Fc[k] += T_b in bond order (he_band_torque's law; the open chain's order when the list is
 * the chain's). A block of bonds at a time: their differences gathered first, then the torques two per SSE2
 * instruction where there is SSE2, then scattered; no call per bond. */
static void cubic_edges(const he_plant_t *p, int ch, const double *restrict xc, double *restrict Fc)
{
    enum { BLK = 64 };
    double T[BLK];
    const int nb = p->nbond;
    const int32_t *restrict bd = p->bonds;
    const double L = p->lever[ch], bs = p->band_scale;
    const he_band_law_t law = he_band_law(p, ch);
    const double *ks = p->kscale[ch];
#ifdef __SSE2__
    const he_band_law2_t law2 = he_band_law2(&law);
    const __m128d Lv = _mm_set1_pd(L), bsv = _mm_set1_pd(bs);
#endif
    for (int b0 = 0; b0 < nb; b0 += BLK) {
        int m = nb - b0 < BLK ? nb - b0 : BLK, i = 0;
        const int32_t *ib = bd + 2 * b0;
        const double *kb = ks + b0;
        for (int q = 0; q < m; q++)
            T[q] = xc[ib[2 * q]] - xc[ib[2 * q + 1]];
#ifdef __SSE2__
        for (; i + 2 <= m; i += 2) {
            __m128d u = _mm_mul_pd(Lv, _mm_loadu_pd(T + i));
            __m128d kbl = _mm_mul_pd(_mm_mul_pd(_mm_loadu_pd(kb + i), bsv), Lv);
            _mm_storeu_pd(T + i, _mm_mul_pd(kbl, he_band_diff2(&law2, u)));
        }
#endif
        for (; i < m; i++)
            T[i] = kb[i] * bs * L * he_band_diff(&law, L * T[i]);
        for (i = 0; i < m; i++) {
            Fc[ib[2 * i]] -= T[i];
            Fc[ib[2 * i + 1]] += T[i];
        }
    }
}

/* Band torques of an edge list for the other laws (linear bands, the geometric beta form): he_band_torque on
 * each bond, reciprocal (-T on i, +T on k) except the geometric form, which is evaluated from each end. */
static void other_edges(const he_plant_t *p, int ch, const double *xc, double *Fc)
{
    const int32_t *bd = p->bonds;
    if (p->bands == HE_BANDS_LINEAR || ch == 0 || p->beta_geometry == HE_BETA_SMALL) {
        for (int b = 0; b < p->nbond; b++) {
            int i = bd[2 * b], k = bd[2 * b + 1];
            double T = he_band_torque(p, ch, b, xc[i], xc[k]);
            Fc[i] -= T;
            Fc[k] += T;
        }
        return;
    }
    for (int b = 0; b < p->nbond; b++) {
        int i = bd[2 * b], k = bd[2 * b + 1];
        Fc[i] -= he_band_torque(p, ch, b, xc[i], xc[k]);
        Fc[k] -= he_band_torque(p, ch, b, xc[k], xc[i]);
    }
}

/* The band torques of an edge list on chain ch (out of line: the open chain's callers keep their size). */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static void edges_band(const he_plant_t *p, int ch, const double *xc, double *Fc)
{
    if (p->bands == HE_BANDS_CUBIC && (ch == 0 || p->beta_geometry == HE_BETA_SMALL))
        cubic_edges(p, ch, xc, Fc);
    else
        other_edges(p, ch, xc, Fc);
}

/* R of every cell, clipped to +-react_limit, added to F (he_reaction and the clip of he_plant_torques, the same
 * operations; two cells per SSE2 instruction where there is SSE2). */
static void add_reaction(const he_plant_t *p, const double *restrict x, double *restrict F)
{
    const int n = p->n;
    const double lim = p->react_limit, nlim = -p->react_limit;
    int j = 0;
    if (p->react_cell) {
        /* per-cell parameters: each cell's own law, the same operations as the uniform loops below */
        for (; j < n; j++) {
            double ra, rb;
            he_reaction_cell(p, j, x[j], x[n + j], &ra, &rb);
            ra = ra > lim ? lim : (ra < nlim ? nlim : ra);
            rb = rb > lim ? lim : (rb < nlim ? nlim : rb);
            F[j] += ra;
            F[n + j] += rb;
        }
        return;
    }
#ifdef __SSE2__
    const __m128d sign = _mm_set1_pd(-0.0), zero = _mm_setzero_pd();
    const __m128d k2 = _mm_set1_pd(p->k2), k1 = _mm_set1_pd(p->k1), k1a = _mm_set1_pd(p->k1 * p->astar);
    const __m128d kab = _mm_set1_pd(p->k_ab), sig = _mm_set1_pd(p->sigma);
    const __m128d limv = _mm_set1_pd(lim), nlimv = _mm_set1_pd(nlim);
    for (; j + 2 <= n; j += 2) {
        __m128d al = _mm_loadu_pd(x + j), be = _mm_loadu_pd(x + n + j);
        __m128d ax = _mm_andnot_pd(sign, al);
        __m128d in = _mm_mul_pd(k2, ax), out = _mm_sub_pd(_mm_mul_pd(k1, ax), k1a);
        __m128d mi = _mm_cmpgt_pd(in, out);
        __m128d psi = _mm_or_pd(_mm_and_pd(mi, in), _mm_andnot_pd(mi, out));
        psi = _mm_xor_pd(psi, _mm_and_pd(_mm_cmplt_pd(al, zero), sign));
        __m128d ra = _mm_sub_pd(_mm_sub_pd(_mm_mul_pd(kab, _mm_sub_pd(be, al)), psi), _mm_mul_pd(sig, be));
        __m128d rb = _mm_mul_pd(kab, _mm_sub_pd(al, be));
        __m128d g = _mm_cmpgt_pd(ra, limv), l = _mm_cmplt_pd(ra, nlimv);
        ra = _mm_or_pd(_mm_and_pd(g, limv), _mm_andnot_pd(g, _mm_or_pd(_mm_and_pd(l, nlimv), _mm_andnot_pd(l, ra))));
        g = _mm_cmpgt_pd(rb, limv);
        l = _mm_cmplt_pd(rb, nlimv);
        rb = _mm_or_pd(_mm_and_pd(g, limv), _mm_andnot_pd(g, _mm_or_pd(_mm_and_pd(l, nlimv), _mm_andnot_pd(l, rb))));
        _mm_storeu_pd(F + j, _mm_add_pd(_mm_loadu_pd(F + j), ra));
        _mm_storeu_pd(F + n + j, _mm_add_pd(_mm_loadu_pd(F + n + j), rb));
    }
#endif
    for (; j < n; j++) {
        double ra, rb;
        he_reaction(p, x[j], x[n + j], &ra, &rb);
        /* actuator limit: the motor can apply at most kt*vmax in either direction */
        ra = ra > lim ? lim : (ra < nlim ? nlim : ra);
        rb = rb > lim ? lim : (rb < nlim ? nlim : rb);
        F[j] += ra;
        F[n + j] += rb;
    }
}

/* The band torques of chain ch added into Fc: an edge list (ring, sheet), else the open chain's bonds (j, j+1) in
 * order, reciprocal (-T on j, +T on j+1) except the geometric beta form, evaluated from each end. */
#if defined(__GNUC__)
__attribute__((always_inline))   /* (he_plant_torques' hot path, as cubic_bonds) */
#endif
static inline void band_torques(const he_plant_t *p, int ch, const double *xc, double *Fc)
{
    const int n = p->n;
    if (p->bonds) {
        edges_band(p, ch, xc, Fc);
    } else if (p->bands == HE_BANDS_CUBIC && (ch == 0 || p->beta_geometry == HE_BETA_SMALL)) {
        cubic_bonds(p, ch, xc, Fc);                               /* the loop below, unrolled for this law */
    } else if (p->bands == HE_BANDS_LINEAR || (ch == 0 || p->beta_geometry == HE_BETA_SMALL)) {
        for (int j = 0; j + 1 < n; j++) {
            double T = he_band_torque(p, ch, j, xc[j], xc[j + 1]);
            Fc[j] -= T;
            Fc[j + 1] += T;
        }
    } else {
        for (int j = 0; j + 1 < n; j++) {
            Fc[j] -= he_band_torque(p, ch, j, xc[j], xc[j + 1]);
            Fc[j + 1] -= he_band_torque(p, ch, j, xc[j + 1], xc[j]);
        }
    }
}

void he_plant_torques(const he_plant_t *p, double t, const double *x, double *F)
{
    int n = p->n;
    for (int ch = 0; ch < 2; ch++) {
        const double *xc = x + ch * n;
        double *Fc = F + ch * n;
        const double *mg = p->mgain[ch], *vo = p->volt[ch];
        for (int j = 0; j < n; j++)
            Fc[j] = mg[j] * vo[j];                                /* Kt*V */
        band_torques(p, ch, xc, Fc);
    }
    if (p->reaction == HE_REACT_IDEAL)
        add_reaction(p, x, F);
    for (int i = 0; i < p->npert; i++) {
        const he_pert_t *q = &p->pert[i];
        if (t >= q->t0 && t < q->t1)
            F[q->chain * n + q->cell] += q->torque;    /* P_j(t) */
    }
}

void he_plant_band_torques(const he_plant_t *p, const double *x, double *F)
{
    int n = p->n;
    for (int ch = 0; ch < 2; ch++) {
        const double *xc = x + ch * n;
        double *Fc = F + ch * n;
        band_torques(p, ch, xc, Fc);
    }
}

int he_plant_nswitch(const he_plant_t *p)
{
    int n = p->n, m = 0;
    if (p->bands == HE_BANDS_CUBIC)
        m += 4 * he_plant_nbond(p);
    if (p->reaction == HE_REACT_IDEAL)
        m += isfinite(p->react_limit) ? 5 * n : n;
    return m;
}

/* Each entry is the very branch condition of the force law (band_force's d > 0, he_reaction's in > out, the clip's
 * ra > lim and ra < -lim), on operands computed by the same expressions. */
int he_plant_switches(const he_plant_t *p, const double *x, unsigned char *side)
{
    int n = p->n, m = 0;
    if (p->bands == HE_BANDS_CUBIC) {
        const int nb = he_plant_nbond(p);
        for (int ch = 0; ch < 2; ch++) {
            const double *xc = x + ch * n;
            double L = p->lever[ch], d0 = p->delta0[ch];
            for (int j = 0; j < nb; j++) {
                /* bond j's cells: (j, j+1) on the open chain, else the edge list's pair */
                int i0 = p->bonds ? p->bonds[2 * j] : j, i1 = p->bonds ? p->bonds[2 * j + 1] : j + 1;
                if (ch == 0 || p->beta_geometry == HE_BETA_SMALL) {
                    double u = L * (xc[i0] - xc[i1]);
                    side[m++] = d0 + u > 0.0;
                    side[m++] = d0 - u > 0.0;
                } else {
                    /* he_band_torque's geometric stretches (the bond seen from i1 swaps them, bit for bit) */
                    double a = p->lattice_m;
                    double ds = sin(xc[i0]) - sin(xc[i1]), dc = cos(xc[i0]) - cos(xc[i1]);
                    double xp = a + L * ds, xm = a - L * ds, yy = L * dc;
                    double lp = sqrt(xp * xp + yy * yy), lm = sqrt(xm * xm + yy * yy);
                    side[m++] = d0 + (lp - a) > 0.0;
                    side[m++] = d0 + (lm - a) > 0.0;
                }
            }
        }
    }
    if (p->reaction == HE_REACT_IDEAL) {
        int clip = isfinite(p->react_limit);
        const double *c = p->react_cell;
        for (int j = 0; j < n; j++) {
            double ax = fabs(x[j]);
            double k1 = c ? c[HE_RC_K1 * n + j] : p->k1, k2 = c ? c[HE_RC_K2 * n + j] : p->k2;
            double ast = c ? c[HE_RC_ASTAR * n + j] : p->astar;
            side[m++] = k2 * ax > k1 * ax - k1 * ast;     /* he_reaction's in > out */
            if (clip) {
                double ra, rb;
                he_reaction_cell(p, j, x[j], x[n + j], &ra, &rb);
                side[m++] = ra > p->react_limit;
                side[m++] = ra < -p->react_limit;
                side[m++] = rb > p->react_limit;
                side[m++] = rb < -p->react_limit;
            }
        }
    }
    return m;
}

/* The largest sum over a cell of |kscale| of its bonds (an edge list's Gershgorin row, in units of kb), in a
 * scratch array of n doubles; without memory for it, nbond * max|kscale| (no cell has more bonds than that). */
static double edge_row_max(const he_plant_t *p, int ch)
{
    const double *ks = p->kscale[ch];
    double *row = calloc((size_t)p->n, sizeof(double)), m = 0.0;
    if (!row) {
        for (int b = 0; b < p->nbond; b++)
            m = fabs(ks[b]) > m ? fabs(ks[b]) : m;
        return (double)p->nbond * m;
    }
    for (int b = 0; b < p->nbond; b++) {
        row[p->bonds[2 * b]] += fabs(ks[b]);
        row[p->bonds[2 * b + 1]] += fabs(ks[b]);
    }
    for (int j = 0; j < p->n; j++)
        m = row[j] > m ? row[j] : m;
    free(row);
    return m;
}

void he_plant_bounds(const he_plant_t *p, double w2[2], double cmin[2], double cmax[2], double rate[2])
{
    /* Gershgorin bound of the linearised stiffness rows:
     *   alpha: 4*kband + max|k_ab + psi''| + |k_ab - sigma|
     *   beta : 4*kband + 2|k_ab|
     * (the open chain; an edge list's 4 is 2 x the most bonds at a cell, weighted by their factors)
     * kband: linear k*max(kscale); cubic s*2*L^2*max f' over [0, delta_max]
     * (f' is convex, so its maximum is at an end), plus the geometric tension term. */
    for (int ch = 0; ch < 2; ch++) {
        /* ksmax: the open chain's largest factor, the row's bonds counted by the 4 (two bonds, each kb on the
         * diagonal and kb off it); an edge list's rows: the largest sum of |factor| over a cell's bonds, times 2 */
        double ksmax = p->bonds ? 0.5 * edge_row_max(p, ch) : 0.0;
        for (int j = 0; !p->bonds && j + 1 < p->n; j++)
            ksmax = fabs(p->kscale[ch][j]) > ksmax ? fabs(p->kscale[ch][j]) : ksmax;
        if (p->n < 2)
            ksmax = 0.0;
        double kb;
        if (p->bands == HE_BANDS_LINEAR) {
            kb = fabs(p->k_lin[ch]);
        } else {
            double L = p->lever[ch];
            double dmax = p->delta_max[ch];
            double s0 = fabs(he_cubic_slope(p->coef[ch], 0.0)), s1 = fabs(he_cubic_slope(p->coef[ch], dmax));
            kb = fabs(p->band_scale) * 2.0 * L * L * (s0 > s1 ? s0 : s1);
            if (ch == 1 && p->beta_geometry == HE_BETA_GEOMETRIC)
                kb += fabs(p->band_scale) * 2.0 * fabs(he_cubic(p->coef[ch], dmax)) * L * L / p->lattice_m;
        }
        double K = 4.0 * kb * ksmax + he_react_stiffness(p, ch);
        double c_lo = INFINITY, c_hi = 0.0;
        for (int j = 0; j < p->n; j++) {
            double c = he_damping(p, ch, j);
            c_lo = c < c_lo ? c : c_lo;
            c_hi = c > c_hi ? c : c_hi;
        }
        if (p->inertia) {
            w2[ch] = K / p->I[ch];
            cmin[ch] = c_lo / p->I[ch];
            cmax[ch] = c_hi / p->I[ch];
            rate[ch] = 0.0;
        } else {
            w2[ch] = 0.0;
            cmin[ch] = c_lo;
            cmax[ch] = c_hi;
            rate[ch] = c_lo > 0.0 ? K / c_lo : INFINITY;
        }
    }
}
