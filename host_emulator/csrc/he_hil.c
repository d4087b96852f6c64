/* Closed loop of the compiled cell firmware with the plant (equations in he_hil.h). */
#include <math.h>
#include <stdlib.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include "he_band.h"
#include "he_hil.h"
#include "he_step.h"

static const uint8_t gray_ab[4] = {0u, 1u, 3u, 2u};

#if defined(__GNUC__)
#define HE_LIKELY(x) __builtin_expect(!!(x), 1)
#else
#define HE_LIKELY(x) (x)
#endif

/* From this many cells on, the tick prefetches the cell 4 ahead (below, the cells fit the L1 cache anyway). */
#define HE_HIL_PREFETCH_CELLS 64

int he_gray(int32_t count) { return gray_ab[(uint32_t)count & 3u]; }

/* xorshift64*: 64-bit state, top 53 bits as a uniform in (0, 1) */
static double uniform(he_hil_t *h)
{
    uint64_t x = h->rng;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    h->rng = x;
    return ((double)((x * 2685821657736338717ULL) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double gauss(he_hil_t *h)
{
    /* Box-Muller */
    double u1 = uniform(h), u2 = uniform(h);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

static inline int32_t encoder_feed(he_hil_t *h, int i, double theta)
{
    double c = theta * h->counts_per_rad;
    if (h->jitter_counts > 0.0)
        c += h->jitter_counts * gauss(h);
    if (c > 2.0e9)
        c = 2.0e9;
    if (c < -2.0e9)
        c = -2.0e9;
    /* floor(c) for |c| <= 2e9 (c finite: the plant step checked the state): the truncation, one less
     * when that rounded a negative fraction up; the same integer as floor(), without the libm call */
    int32_t target = (int32_t)c;
    target -= (double)target > c;
    int32_t cur = h->count[i];
    mc_quad_t *q = &h->quad[i];
    while (cur != target) {           /* one Gray step per count */
        cur += cur < target ? 1 : -1;
        mc_quad_update(q, (uint8_t)he_gray(cur));
    }
    if (h->glitch_prob > 0.0 && uniform(h) < h->glitch_prob) {
        uint8_t ab = (uint8_t)he_gray(cur);
        mc_quad_update(q, (uint8_t)(ab ^ 3u));
        mc_quad_update(q, ab);
        h->glitches++;
    }
    h->count[i] = cur;
    return cur;
}

int32_t he_encoder_feed(he_hil_t *h, int i, double theta) { return encoder_feed(h, i, theta); }

void he_hil_volt_table(double *tab, int32_t top, double supply_v)
{
    for (int32_t d = 0; d <= top; d++)
        tab[d] = (double)d / (double)top * supply_v;
}

void he_hil_sync_encoders(he_hil_t *h, const double *x)
{
    for (int i = 0; i < 2 * h->n; i++) {
        int32_t c = (int32_t)floor(x[i] * h->counts_per_rad);
        h->count[i] = c;
        mc_quad_init(&h->quad[i], (uint8_t)he_gray(c));
        mc_quad_set_pos(&h->quad[i], c);
    }
}

/* ---- fast path of the plant step (bit-identical to he_advance for the configuration it accepts) ----
 * The hil default runs one symplectic-Euler step per control tick on the cubic small-angle bands with no
 * floating-point reaction. he_advance recomputes per step what a tick holds fixed (Kt V, and
 * 1 + h C / I with C = eta + m/S_L: three divisions per cylinder) and makes five passes over the state
 * (forces, bonds, update, flush, checks). On the open chain plant_step_fast does the same arithmetic, in the same order on
 * the same operands, in two passes over the state (update and checks; then the next step's bond torques and
 * the stretch test) with the per-tick terms cached; on an edge list (ring, sheet) plant_step_edges does it in
 * three (the bond torques, the update and checks, the stretch test). Any other configuration, and every step during which a
 * perturbation is on, goes through he_advance. */
/* MAINTENANCE: plant_step_fast re-does he_plant_forces + he_advance for this configuration only. A new term
 * in he_plant_forces (a torque or voltage limit, another force) must either be added to plant_step_fast in
 * the same order or make fast_ok() return 0 when it is active; test_golden.py's fast-vs-generic test and the
 * hil tests that compare against he_advance catch a mismatch only if they exercise the new term. */
static int fast_ok(const he_plant_t *p, int stepper)
{
    return stepper == HE_STEP_SYMPLECTIC && p->inertia && p->bands == HE_BANDS_CUBIC
        && p->beta_geometry == HE_BETA_SMALL && p->reaction == HE_REACT_NONE && p->n >= 1
        && p->n <= HE_MAX_CELLS;   /* the open chain (plant_step_fast) or an edge list (plant_step_edges) */
}

static int pert_active(const he_plant_t *p, double t)
{
    for (int i = 0; i < p->npert; i++)
        if (t >= p->pert[i].t0 && t < p->pert[i].t1)
            return 1;
    return 0;
}

/* The scratch of he_hil_run_ws (he_hil.h): heap arrays sized by the cell count, set up by he_hil_ws_open from
 * h and its plant, which nothing may change while it is open. */
struct he_hil_ws {
    he_hil_t *h;
    int n, fast;
    int edges;         /* the plant has an edge list: the fast step is plant_step_edges */
    int bonds_ok;      /* bond[] holds the bond torques of the current x (fast path) */
    double dt;         /* tick_s / substeps */
    double *mv;        /* [2n] Kt V per cylinder, held over the tick */
    double *den;       /* [2n] 1 + dt C / I for the tick */
    double *den_sel;   /* [2][2n] ... while the driver coasts (m = 0), then while it is awake (m = Kt) */
    double *bond;      /* [2n] bond torques T(j, j+1) per chain, [n-1] of each used */
    double *kbl;       /* [2n] kscale_j * band_scale * lever per bond (the first two factors of T) */
    double *enc_lo;    /* [2n] (double)count[i]: the encoder needs no step while lo <= theta cpr < lo + 1 */
    double *mvtab;     /* [volt_tab_top + 1] Kt volt_tab[d]: the fast path's |Kt V| by duty (NULL: no table) */
    int32_t *moved;    /* [2n] encoders whose angle left the count window in the last fast step */
    int volts_stale;   /* fast ticks ran since p->volt, p->mgain were last written (sync_volts) */
};
typedef struct he_hil_ws hil_ws_t;

void he_hil_ws_close(he_hil_ws_t *w) { free(w); }

int he_hil_ws_open(he_hil_t *h, he_hil_ws_t **out)
{
    if (!out)
        return HE_ERR_ARG;
    *out = NULL;
    if (!h || !h->plant || !h->cells || !h->quad || !h->count || h->n != h->plant->n || h->n < 1
        || h->n > HE_MAX_CELLS || h->substeps < 1 || !(h->tick_s > 0.0))
        return HE_ERR_ARG;
    const he_plant_t *p = h->plant;
    int n = h->n, n2 = 2 * n;
    /* one block: the header, 7 arrays of 2n doubles, the moved list and the table of Kt V by duty */
    size_t head = (sizeof(hil_ws_t) + sizeof(double) - 1) / sizeof(double) * sizeof(double);
    int32_t tabn = h->volt_tab && h->volt_tab_top >= 1 ? h->volt_tab_top + 1 : 0;
    hil_ws_t *w = malloc(head + ((size_t)8 * (size_t)n2 + (size_t)tabn) * sizeof(double));
    if (!w)
        return HE_ERR_NOMEM;
    double *b = (double *)(void *)((char *)w + head);
    w->h = h;
    w->n = n;
    w->dt = h->tick_s / h->substeps;
    w->fast = fast_ok(p, h->stepper);
    w->edges = p->bonds != NULL;
    w->bonds_ok = 0;
    w->mv = b;
    w->den = b + n2;
    w->den_sel = b + 2 * n2;   /* 2 x 2n */
    w->bond = b + 4 * n2;
    w->kbl = b + 5 * n2;
    w->enc_lo = b + 6 * n2;
    w->moved = (int32_t *)(void *)(b + 7 * n2);   /* 2n int32 in n2 doubles' room */
    w->mvtab = tabn ? b + 8 * n2 : NULL;
    w->volts_stale = 0;
    for (int i = 0; i < n2; i++)
        w->enc_lo[i] = (double)h->count[i];
    /* Kt (dir ? v : -v) = dir ? Kt v : -(Kt v) exactly: the table holds the products the tick would form */
    for (int32_t d = 0; d < tabn; d++)
        w->mvtab[d] = h->kt * h->volt_tab[d];
    if (w->fast) {
        /* 1 + h C / I with C = eta + m / S_L (he_plant_forces, he_advance) for m = Kt (driving) and m = 0
         * (coasting): the only two values a tick can give, so no division per tick is left for them */
        double dt = w->dt;
        for (int ch = 0; ch < 2; ch++)
            for (int j = 0; j < n; j++) {
                w->den_sel[n2 + ch * n + j] = 1.0 + dt * (p->eta[ch][j] + h->kt / p->speed_const) / p->I[ch];
                w->den_sel[ch * n + j] = 1.0 + dt * (p->eta[ch][j] + 0.0 / p->speed_const) / p->I[ch];
                /* he_band_torque's ks * band_scale * L * (g+ - g-), evaluated left to right (the open chain) */
                w->kbl[ch * n + j] = j + 1 < n && !w->edges ? p->kscale[ch][j] * p->band_scale * p->lever[ch] : 0.0;
            }
    }
    *out = w;
    return HE_OK;
}

/* Bond torques T(j, j+1) = s*L*[g(delta0 + u) - g(delta0 - u)], u = L (x_j - x_j+1) (he_band_torque) of both
 * chains into w->bond, and he_plant_range_check's stretch test delta0 + L|x_j - x_j+1| > lim on the same x
 * (L |d| = |L d| for L > 0, so it reuses u): nonzero when some bond fails it. Two bonds per SSE2 instruction
 * where there is SSE2 (each lane does the scalar IEEE operations), the rest one at a time. */
static int fast_bonds(const he_plant_t *p, hil_ws_t *w, const double *restrict x)
{
    int n = w->n, over_any = 0;
    for (int ch = 0; ch < 2; ch++) {
        const double L = p->lever[ch], d0 = p->delta0[ch];
        const double lim = HE_BAND_STOP_FACTOR * p->delta_max[ch];
        const he_band_law_t law = he_band_law(p, ch);
        const double *restrict xc = x + ch * n;
        const double *restrict kbl = w->kbl + ch * n;
        double *restrict T = w->bond + ch * n;
        int j = 0;
#ifdef __SSE2__
        {
            const he_band_law2_t law2 = he_band_law2(&law);
            const __m128d sign = _mm_set1_pd(-0.0), d0v = law2.d0, Lv = _mm_set1_pd(L), limv = _mm_set1_pd(lim);
            __m128d over = _mm_setzero_pd();
            for (;; j += 2) {                      /* bonds (j, j+1), (j+1, j+2) */
                if (j + 2 >= n) {
                    if (j != n - 2 || n < 3)
                        break;
                    j = n - 3;                 /* one bond left: it and the one before (the same value again) */
                }
                __m128d u = _mm_mul_pd(Lv, _mm_sub_pd(_mm_loadu_pd(xc + j), _mm_loadu_pd(xc + j + 1)));
                _mm_storeu_pd(T + j, _mm_mul_pd(_mm_loadu_pd(kbl + j), he_band_diff2(&law2, u)));
                over = _mm_or_pd(over, _mm_cmpgt_pd(_mm_add_pd(d0v, _mm_andnot_pd(sign, u)), limv));
            }
            over_any |= _mm_movemask_pd(over);
        }
#endif
        for (; j + 1 < n; j++) {
            double u = L * (xc[j] - xc[j + 1]);
            T[j] = kbl[j] * he_band_diff(&law, u);
            over_any |= d0 + fabs(u) > lim;
        }
    }
    return over_any;
}

static inline void sympl_update(double F, double dt, double I, double den, double *x, double *v)
{
    double vj = (*v + dt * F / I) / den;
    double xj = *x + dt * vj;
    *x = fabs(xj) < HE_TINY_RAD ? 0.0 : xj;
    *v = fabs(vj) < HE_TINY_RAD ? 0.0 : vj;
}

/* floor(c) == count exactly when count <= c < count + 1 (count + 1 is exact in a double); NaN is outside */
static inline int in_window(double lo, double c) { return lo <= c && c < lo + 1.0; }

static inline int out_of_bounds(double x, double v)
{
    return !(fabs(x) <= HE_ANGLE_LIMIT_RAD) | !(fabs(v) <= HE_SPEED_LIMIT_RAD_S);
}

/* An encoder whose count must move: encoder_feed without its random draws (noise off), the same steps in the
 * same order; keeps w->enc_lo in step with h->count. */
static void encoder_move(he_hil_t *h, hil_ws_t *w, int i, double theta)
{
    double c = theta * h->counts_per_rad;
    c = c > 2.0e9 ? 2.0e9 : c;
    c = c < -2.0e9 ? -2.0e9 : c;
    int32_t target = (int32_t)c;
    target -= (double)target > c;
    int32_t cur = h->count[i];
    if (cur == target)
        return;
    mc_quad_t *q = &h->quad[i];
    while (cur != target) {
        cur += cur < target ? 1 : -1;
        mc_quad_update(q, (uint8_t)he_gray(cur));
    }
    h->count[i] = cur;
    w->enc_lo[i] = (double)cur;
}

/* ---- fast path of the plant step (bit-identical to he_advance for the configuration it accepts) ----
 * One step of size w->dt with the tick's w->mv = Kt V and w->den = 1 + dt C / I per cylinder (as
 * he_plant_forces / he_advance form them) and w->bond = the bond torques of x (fast_bonds):
 *   F_j = (Kt V_j + T(j-1, j)) - T(j, j+1) in he_plant_forces' order (the end cylinders have one bond and no
 *   "+ 0.0", which would turn a -0.0 into +0.0); v1 = (v0 + h F/I) / (1 + h C/I), x1 = x0 + h v1 (he_advance),
 *   then he_flush_tiny and he_state_check's bounds (NaN fails them);
 * then the bond torques of the new x, which the next step needs, and with them he_plant_range_check's stretch
 * test of the new x. HE_OK or the code he_advance would return (on an error w->bond is stale).
 * With quiet (noise off), the update pass also tests every new angle against its encoder's count window
 * (encoders_quiet's test) and, once the step passed its checks, moves the encoders that left it (encoders_quiet's
 * work, in one pass less over the state; the encoders are independent, so the order does not matter). */
static int plant_step_fast(const he_plant_t *p, hil_ws_t *w, double *restrict x, double *restrict v, const int quiet)
{
    int n = w->n, bad = 0, nm = 0;
    const double dt = w->dt, cpr = w->h->counts_per_rad;
    const double *restrict lo = w->enc_lo;
    int32_t *restrict moved = w->moved;
    for (int ch = 0; ch < 2; ch++) {
        const double I = p->I[ch];
        double *restrict xc = x + ch * n;
        double *restrict vc = v + ch * n;
        const double *restrict mvc = w->mv + ch * n;
        const double *restrict denc = w->den + ch * n;
        const double *restrict T = w->bond + ch * n;
        const double *restrict loc = lo + ch * n;
        if (n == 1) {
            sympl_update(mvc[0], dt, I, denc[0], xc, vc);
            bad |= out_of_bounds(xc[0], vc[0]);
            if (quiet && !in_window(loc[0], xc[0] * cpr))
                moved[nm++] = ch * n;
            continue;
        }
        sympl_update(mvc[0] - T[0], dt, I, denc[0], xc, vc);
        bad |= out_of_bounds(xc[0], vc[0]);
        if (quiet && !in_window(loc[0], xc[0] * cpr))
            moved[nm++] = ch * n;
        int j = 1;
#ifdef __SSE2__
        {
            const __m128d sign = _mm_set1_pd(-0.0), tiny = _mm_set1_pd(HE_TINY_RAD);
            const __m128d xlim = _mm_set1_pd(HE_ANGLE_LIMIT_RAD), vlim = _mm_set1_pd(HE_SPEED_LIMIT_RAD_S);
            const __m128d dtv = _mm_set1_pd(dt), Iv = _mm_set1_pd(I), cp = _mm_set1_pd(cpr), one = _mm_set1_pd(1.0);
            __m128d ok = _mm_castsi128_pd(_mm_set1_epi32(-1));
            for (; j + 2 < n; j += 2) {        /* cylinders j, j+1, both interior */
                __m128d F = _mm_sub_pd(_mm_add_pd(_mm_loadu_pd(mvc + j), _mm_loadu_pd(T + j - 1)), _mm_loadu_pd(T + j));
                __m128d vj = _mm_div_pd(_mm_add_pd(_mm_loadu_pd(vc + j), _mm_div_pd(_mm_mul_pd(dtv, F), Iv)),
                                        _mm_loadu_pd(denc + j));
                __m128d xj = _mm_add_pd(_mm_loadu_pd(xc + j), _mm_mul_pd(dtv, vj));
                xj = _mm_andnot_pd(_mm_cmplt_pd(_mm_andnot_pd(sign, xj), tiny), xj);
                vj = _mm_andnot_pd(_mm_cmplt_pd(_mm_andnot_pd(sign, vj), tiny), vj);
                _mm_storeu_pd(xc + j, xj);
                _mm_storeu_pd(vc + j, vj);
                ok = _mm_and_pd(ok, _mm_cmple_pd(_mm_andnot_pd(sign, xj), xlim));
                ok = _mm_and_pd(ok, _mm_cmple_pd(_mm_andnot_pd(sign, vj), vlim));
                if (quiet) {
                    __m128d c = _mm_mul_pd(xj, cp), l = _mm_loadu_pd(loc + j);
                    __m128d in = _mm_and_pd(_mm_cmple_pd(l, c), _mm_cmplt_pd(c, _mm_add_pd(l, one)));
                    if (_mm_movemask_pd(in) != 3) {
                        moved[nm++] = ch * n + j;
                        moved[nm++] = ch * n + j + 1;
                    }
                }
            }
            bad |= _mm_movemask_pd(ok) != 3;
        }
#endif
        for (; j + 1 < n; j++) {
            sympl_update((mvc[j] + T[j - 1]) - T[j], dt, I, denc[j], xc + j, vc + j);
            bad |= out_of_bounds(xc[j], vc[j]);
            if (quiet && !in_window(loc[j], xc[j] * cpr))
                moved[nm++] = ch * n + j;
        }
        sympl_update(mvc[n - 1] + T[n - 2], dt, I, denc[n - 1], xc + n - 1, vc + n - 1);
        bad |= out_of_bounds(xc[n - 1], vc[n - 1]);
        if (quiet && !in_window(loc[n - 1], xc[n - 1] * cpr))
            moved[nm++] = ch * n + n - 1;
    }
    if (bad) {
        w->bonds_ok = 0;
        return he_state_check(2 * n, x, v);    /* the first bad entry decides NONFINITE or DIVERGED */
    }
    int over = fast_bonds(p, w, x);
    w->bonds_ok = !over;
    if (over)
        return HE_ERR_BAND;
    for (int k = 0; k < nm; k++)
        encoder_move(w->h, w, moved[k], x[moved[k]]);
    return HE_OK;
}

/* ---- fast plant step on an edge list (bit-identical to he_advance for the configuration fast_ok accepts) ----
 * F = Kt V (w->mv, the products he_plant_forces forms), then he_plant_band_torques' bonds in bond order (the
 * general path's he_plant_torques without reaction or an active perturbation); then per cylinder
 * v1 = (v0 + h F/I) / (1 + h C/I), x1 = x0 + h v1 with the tick's cached 1 + h C/I, he_flush_tiny, the bounds of
 * he_state_check (NaN fails them), he_plant_range_check, and (quiet) the encoders that left their count window,
 * as plant_step_fast does. w->bond serves as F. */
#if defined(__GNUC__)
__attribute__((noinline))   /* out of the tick loop: the open chain's loop keeps its registers */
#endif
static int plant_step_edges(const he_plant_t *p, hil_ws_t *w, double *restrict x, double *restrict v, const int quiet)
{
    const int n = w->n, n2 = 2 * n;
    const double dt = w->dt, cpr = w->h->counts_per_rad;
    const double *restrict lo = w->enc_lo;
    int32_t *restrict moved = w->moved;
    double *restrict F = w->bond;
    int bad = 0, nm = 0;
    for (int i = 0; i < n2; i++)
        F[i] = w->mv[i];
    he_plant_band_torques(p, x, F);
    for (int ch = 0; ch < 2; ch++) {
        const double I = p->I[ch];
        for (int i = ch * n; i < (ch + 1) * n; i++) {
            sympl_update(F[i], dt, I, w->den[i], x + i, v + i);
            bad |= out_of_bounds(x[i], v[i]);
            if (quiet && !in_window(lo[i], x[i] * cpr))
                moved[nm++] = i;
        }
    }
    if (bad)
        return he_state_check(n2, x, v);    /* the first bad entry decides NONFINITE or DIVERGED */
    if (he_plant_range_check(p, x, NULL) != HE_OK)
        return HE_ERR_BAND;
    for (int k = 0; k < nm; k++)
        encoder_move(w->h, w, moved[k], x[moved[k]]);
    return HE_OK;
}

/* Noise off: every encoder whose floor(theta cpr) left its count moves there (after a general plant step; the
 * fast step does this in its update pass). A quiet encoder costs two compares and no conversion (in_window);
 * NaN fails the compares and takes encoder_move's path, as before. */
static void encoders_quiet(he_hil_t *h, hil_ws_t *w, const double *x)
{
    const double cpr = h->counts_per_rad;
    const double *lo = w->enc_lo;
    int n2 = 2 * w->n, i = 0;
#ifdef __SSE2__
    const __m128d cp = _mm_set1_pd(cpr), one = _mm_set1_pd(1.0);
    for (; i + 2 <= n2; i += 2) {
        __m128d c = _mm_mul_pd(_mm_loadu_pd(x + i), cp), l = _mm_loadu_pd(lo + i);
        __m128d in = _mm_and_pd(_mm_cmple_pd(l, c), _mm_cmplt_pd(c, _mm_add_pd(l, one)));
        if (_mm_movemask_pd(in) != 3) {
            encoder_move(h, w, i, x[i]);
            encoder_move(h, w, i + 1, x[i + 1]);
        }
    }
#endif
    for (; i < n2; i++)
        if (!in_window(lo[i], x[i] * cpr))
            encoder_move(h, w, i, x[i]);
}

/* The motor voltage of a command, +-duty/top * Vs (the table holds the same quotients), as he_plant_forces gets it. */
static inline double drive_volt(const he_hil_t *h, int32_t top, mc_drive_out_t o)
{
    const int tab = h->volt_tab && top == h->volt_tab_top && o.duty <= top;
    double vlt = tab ? h->volt_tab[o.duty] : (double)o.duty / (double)top * h->supply_v;
    return o.dir ? vlt : -vlt;
}

/* Kt duty/top Vs for a duty the table does not hold (out of line: the tick always finds the table) */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static double untabled_mv(const he_hil_t *h, int32_t top, int32_t duty)
{
    return h->kt * ((double)duty / (double)top * h->supply_v);
}

/* p->volt, p->mgain of every cylinder from the cells' current commands: what the general tick writes. The fast
 * tick leaves them to this (the fast plant step reads w->mv, w->den), called before a general plant step and
 * at the end of he_hil_run_ws. */
static void sync_volts(he_hil_t *h, hil_ws_t *w)
{
    he_plant_t *p = h->plant;
    const double kt = h->kt;
    for (int ch = 0; ch < 2; ch++) {
        /* the rows' addresses once (a store through them could alias the plant's pointer members otherwise) */
        double *const volt = p->volt[ch], *const mg = p->mgain[ch];
        const mc_cell_t *c = h->cells;
        for (int j = 0; j < w->n; j++, c++) {
            const mc_drive_out_t o = c->out[ch];
            volt[j] = o.enable ? drive_volt(h, c->drive.pwm_top, o) : 0.0;
            mg[j] = o.enable ? kt : 0.0;
        }
    }
    w->volts_stale = 0;
}

/* One control tick of every cell: the firmware tick on the decoder snapshots, then the motor terms it
 * commands: with fast, w->mv = Kt V and w->den for the fast step (p->volt, p->mgain left to sync_volts);
 * otherwise p->volt, p->mgain for he_plant_forces. pf: prefetch the cell 4 ahead (large lattices). Returns the
 * OR of the cells' fault flags. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline uint32_t cells_loop(he_hil_t *h, hil_ws_t *w, const int fast, const int pf)
{
    he_plant_t *p = h->plant;
    const int n = w->n;
    const double kt = h->kt;
    const double *const mvtab = w->mvtab;
    const int32_t vtop = mvtab ? h->volt_tab_top : -1;
    uint32_t fo = 0;
    mc_cell_t *const cells = h->cells;
    const mc_quad_t *const quad = h->quad;
    double *const mv = w->mv, *const den = w->den;
    const double *const don = w->den_sel + 2 * n, *const doff = w->den_sel;
    double *const volt[2] = {p->volt[0], p->volt[1]}, *const mg[2] = {p->mgain[0], p->mgain[1]};
    for (int j = 0; j < n; j++) {
        mc_quad_snap_t sa, sb;
        mc_cell_t *c = &cells[j];
        /* cache: the hot head of the cell 4 ahead (docs/accuracy.md, Scaling) */
        if (pf && j + 4 < n)
            __builtin_prefetch(&cells[j + 4]);
        mc_quad_snapshot(&quad[j], &sa);
        mc_quad_snapshot(&quad[n + j], &sb);
        fo |= mc_cell_tick(c, &sa, &sb);
        /* the commands as values: the double stores below could alias them otherwise (-fno-strict-aliasing) */
        const mc_drive_out_t out[2] = {c->out[0], c->out[1]};
        const int32_t top = c->drive.pwm_top;
        for (int ch = 0; ch < 2; ch++) {
            const mc_drive_out_t o = out[ch];
            const int i = ch * n + j;
            if (fast) {
                /* F = m V (he_plant_forces): Kt (+-duty/top Vs) from the table, +0.0 when coasting; and
                 * 1 + h C/I by the driver's state */
                if (HE_LIKELY(o.enable)) {
                    double m = HE_LIKELY(top == vtop && o.duty <= top) ? mvtab[o.duty] : untabled_mv(h, top, o.duty);
                    mv[i] = o.dir ? m : -m;
                    den[i] = don[i];
                } else {
                    mv[i] = 0.0 * 0.0;
                    den[i] = doff[i];
                }
            } else if (o.enable) {
                volt[ch][j] = drive_volt(h, top, o);
                mg[ch][j] = kt;
            } else {
                volt[ch][j] = 0.0;
                mg[ch][j] = 0.0;
            }
        }
    }
    if (fast)
        w->volts_stale = 1;
    return fo;
}

/* One call per tick. flatten (GCC, across translation units under -flto) inlines mc_cell_tick, the very
 * firmware function, into the loop, so that snapshots and outputs stay in registers. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((noinline, flatten))
#endif
static uint32_t tick_cells(he_hil_t *h, hil_ws_t *w)
{
    if (w->n >= HE_HIL_PREFETCH_CELLS)
        return w->fast ? cells_loop(h, w, 1, 1) : cells_loop(h, w, 0, 1);
    return w->fast ? cells_loop(h, w, 1, 0) : cells_loop(h, w, 0, 0);
}

int he_hil_run_ws(he_hil_ws_t *w, int64_t n_ticks, double *t, double *x, double *v)
{
    if (!w || !t || !x || !v)
        return HE_ERR_ARG;
    he_hil_t *h = w->h;
    he_plant_t *p = h->plant;
    const int n = w->n, fast = w->fast, noisy = h->jitter_counts > 0.0 || h->glitch_prob > 0.0;
    const double dt = w->dt;
    double t0 = *t;
    uint32_t fo = h->fault_or;
    for (int64_t k = 0; k < n_ticks; k++) {
        fo |= tick_cells(h, w);
        double tk = t0 + (double)k * h->tick_s;
        for (int s = 0; s < h->substeps; s++) {
            double ts = tk + (double)s * dt;
            int rc, stepped_fast = 0;
            if (fast && !pert_active(p, ts + HE_STAGE_EDGE * dt)) {
                if (w->edges) {
                    rc = plant_step_edges(p, w, x, v, !noisy);
                } else {
                    if (!w->bonds_ok)
                        fast_bonds(p, w, x);   /* torques only: the state's checks come after the step */
                    rc = plant_step_fast(p, w, x, v, !noisy);
                }
                stepped_fast = 1;
                ts = ts + (double)1 * dt;
            } else {
                w->bonds_ok = 0;
                if (w->volts_stale)
                    sync_volts(h, w);
                rc = he_advance(p, h->stepper, dt, 1, &ts, x, v);
            }
            if (rc != HE_OK) {
                if (w->volts_stale)
                    sync_volts(h, w);
                h->fault_or = fo;
                *t = ts;
                return rc;
            }
            if (noisy) {
                for (int i = 0; i < 2 * n; i++)
                    w->enc_lo[i] = (double)encoder_feed(h, i, x[i]);
            } else if (!stepped_fast) {
                encoders_quiet(h, w, x);
            }
        }
        h->ticks++;
    }
    if (w->volts_stale)
        sync_volts(h, w);
    h->fault_or = fo;
    *t = t0 + (double)n_ticks * h->tick_s;
    return HE_OK;
}

int he_hil_run(he_hil_t *h, int64_t n_ticks, double *t, double *x, double *v)
{
    hil_ws_t *w;
    int rc = he_hil_ws_open(h, &w);
    if (rc == HE_OK)
        rc = he_hil_run_ws(w, n_ticks, t, x, v);
    he_hil_ws_close(w);
    return rc;
}
