/* Closed loop of the compiled cell firmware with the plant (equations in he_hil.h). */
#include <math.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include "he_hil.h"
#include "he_step.h"
#include "he_step_more.h"

static const uint8_t gray_ab[4] = {0u, 1u, 3u, 2u};

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
 * (forces, bonds, update, flush, checks). plant_step_fast does the same arithmetic, in the same order on
 * the same operands, in one pass per chain with the per-tick terms cached. Any other configuration, and
 * every step during which a perturbation is on, goes through he_advance. */
/* MAINTENANCE: plant_step_fast re-does he_plant_forces + he_advance for this configuration only. A new term
 * in he_plant_forces (a torque or voltage limit, another force) must either be added to plant_step_fast in
 * the same order or make fast_ok() return 0 when it is active; test_golden.py's fast-vs-generic test and the
 * hil tests that compare against he_advance catch a mismatch only if they exercise the new term. */
static int fast_ok(const he_plant_t *p, int stepper)
{
    return stepper == HE_STEP_SYMPLECTIC && p->inertia && p->bands == HE_BANDS_CUBIC
        && p->beta_geometry == HE_BETA_SMALL && p->reaction == HE_REACT_NONE && p->n >= 1
        && p->n <= HE_MAX_CELLS;
}

static int pert_active(const he_plant_t *p, double t)
{
    for (int i = 0; i < p->npert; i++)
        if (t >= p->pert[i].t0 && t < p->pert[i].t1)
            return 1;
    return 0;
}

static inline void sympl_update(double F, double dt, double I, double den, double *x, double *v)
{
    double vj = (*v + dt * F / I) / den;
    double xj = *x + dt * vj;
    *x = fabs(xj) < HE_TINY_RAD ? 0.0 : xj;
    *v = fabs(vj) < HE_TINY_RAD ? 0.0 : vj;
}

/* One step of size dt; mv = Kt V and den = 1 + dt C / I per cylinder (as he_plant_forces / he_advance form
 * them); T is scratch of n doubles (the bond torques). HE_OK or the code he_advance would return. Written as simple loops
 * without cross-iteration dependences so the compiler can run two cylinders per SSE2 instruction: each lane
 * does the very IEEE operations of the scalar code, so the bits do not change. */
static int plant_step_fast(const he_plant_t *p, double dt, const double *restrict mv,
                           const double *restrict den, double *restrict x, double *restrict v,
                           double *restrict T)
{
    int n = p->n;
    int bad = 0, bad_band = 0;
    for (int ch = 0; ch < 2; ch++) {
        const double *restrict c = p->coef[ch];
        const double *restrict ks = p->kscale[ch];
        const double L = p->lever[ch], d0 = p->delta0[ch], bs = p->band_scale, I = p->I[ch];
        const double lim = HE_BAND_STOP_FACTOR * p->delta_max[ch];
        const double c0 = c[0], c1 = c[1], c2 = c[2], c3 = c[3];
        const double slack = p->slack_f0 ? c0 : 0.0;
        double *restrict xc = x + ch * n;
        double *restrict vc = v + ch * n;
        const double *restrict mvc = mv + ch * n;
        const double *restrict denc = den + ch * n;
        /* bond torques T(j, j+1) = s*L*[g(delta0 + u) - g(delta0 - u)], u = L (x_j - x_j+1) (he_band_torque) */
        for (int j = 0; j + 1 < n; j++) {
            double u = L * (xc[j] - xc[j + 1]);
            double dp = d0 + u, dm = d0 - u;
            double gp = c0 + dp * (c1 + dp * (c2 + dp * c3));
            double gm = c0 + dm * (c1 + dm * (c2 + dm * c3));
            gp = dp > 0.0 ? gp : slack;
            gm = dm > 0.0 ? gm : slack;
            T[j] = ks[j] * bs * L * (gp - gm);
        }
        /* F_j = (Kt V_j + T(j-1, j)) - T(j, j+1) in he_plant_forces' order; v1 = (v0 + h F/I) / (1 + h C/I),
         * x1 = x0 + h v1 (he_advance); then he_flush_tiny and the he_state_check bounds */
        /* F_j = (Kt V_j + T(j-1, j)) - T(j, j+1) in he_plant_forces' order (the end cylinders have one bond
         * and no "+ 0.0", which would turn a -0.0 into +0.0); then v1 = (v0 + h F/I) / (1 + h C/I),
         * x1 = x0 + h v1 (he_advance) and he_flush_tiny */
        if (n == 1) {
            sympl_update(mvc[0], dt, I, denc[0], xc, vc);
        } else {
            sympl_update(mvc[0] - T[0], dt, I, denc[0], xc, vc);
            for (int j = 1; j + 1 < n; j++)
                sympl_update((mvc[j] + T[j - 1]) - T[j], dt, I, denc[j], xc + j, vc + j);
            sympl_update(mvc[n - 1] + T[n - 2], dt, I, denc[n - 1], xc + n - 1, vc + n - 1);
        }
        /* he_state_check's bounds (NaN fails them) and he_plant_range_check's stretch test; two lanes at a
         * time where SSE2 is there (the same compares on the same values), the rest one at a time */
        int j = 0;
#ifdef __SSE2__
        {
            const __m128d sign = _mm_set1_pd(-0.0), xlim = _mm_set1_pd(HE_ANGLE_LIMIT_RAD);
            const __m128d vlim = _mm_set1_pd(HE_SPEED_LIMIT_RAD_S), blim = _mm_set1_pd(lim);
            const __m128d d0v = _mm_set1_pd(d0), Lv = _mm_set1_pd(L);
            __m128d ok = _mm_castsi128_pd(_mm_set1_epi32(-1)), over = _mm_setzero_pd();
            for (; j + 2 < n; j += 2) {            /* x[j], x[j+1] and the bonds (j, j+1), (j+1, j+2) */
                __m128d xa = _mm_loadu_pd(xc + j), xb = _mm_loadu_pd(xc + j + 1), va = _mm_loadu_pd(vc + j);
                ok = _mm_and_pd(ok, _mm_cmple_pd(_mm_andnot_pd(sign, xa), xlim));
                ok = _mm_and_pd(ok, _mm_cmple_pd(_mm_andnot_pd(sign, va), vlim));
                __m128d st = _mm_add_pd(d0v, _mm_mul_pd(Lv, _mm_andnot_pd(sign, _mm_sub_pd(xa, xb))));
                over = _mm_or_pd(over, _mm_cmpgt_pd(st, blim));
            }
            bad |= _mm_movemask_pd(ok) != 3;
            bad_band |= _mm_movemask_pd(over) != 0;
        }
#endif
        for (; j < n; j++) {
            bad |= !(fabs(xc[j]) <= HE_ANGLE_LIMIT_RAD) | !(fabs(vc[j]) <= HE_SPEED_LIMIT_RAD_S);
            if (j + 1 < n)
                bad_band |= d0 + L * fabs(xc[j] - xc[j + 1]) > lim;
        }
    }
    if (bad)
        return he_state_check(2 * n, x, v);    /* the first bad entry decides NONFINITE or DIVERGED */
    return bad_band ? HE_ERR_BAND : HE_OK;
}

int he_hil_run(he_hil_t *h, int64_t n_ticks, double *t, double *x, double *v)
{
    he_plant_t *p = h->plant;
    int n = h->n;
    if (!p || n != p->n || h->substeps < 1 || !(h->tick_s > 0.0))
        return HE_ERR_ARG;
    double dt = h->tick_s / h->substeps;
    double t0 = *t;
    int fast = fast_ok(p, h->stepper);
    int n2f = fast ? 2 * n : 1;
    double mv[n2f], den[n2f], den_on[n2f], den_off[n2f], bond[n2f];
    if (fast) {
        /* 1 + h C / I with C = eta + m / S_L (he_plant_forces, he_advance) for m = Kt (driving) and m = 0
         * (coasting): the only two values a tick can give, so no division per tick is left for them */
        for (int ch = 0; ch < 2; ch++)
            for (int j = 0; j < n; j++) {
                den_on[ch * n + j] = 1.0 + dt * (p->eta[ch][j] + h->kt / p->speed_const) / p->I[ch];
                den_off[ch * n + j] = 1.0 + dt * (p->eta[ch][j] + 0.0 / p->speed_const) / p->I[ch];
            }
    }
    for (int64_t k = 0; k < n_ticks; k++) {
        for (int j = 0; j < n; j++) {
            mc_quad_snap_t sa, sb;
            mc_cell_t *c = &h->cells[j];
            /* cache: mc_cell_t is 2192 bytes (velocity ring); at 4096 cells a tick's working set (~1.7 MB)
             * exceeds L2, and the cost per cell rose 1.33x over 1024 cells. Fetching the hot head (the
             * first 192 bytes) of a cell 4 ahead brings it back to ~1.1x (docs/accuracy.md, Scaling). */
            if (j + 4 < n) {
                const char *ahead = (const char *)&h->cells[j + 4];
                __builtin_prefetch(ahead);
                __builtin_prefetch(ahead + 64);
                __builtin_prefetch(ahead + 128);
            }
            mc_quad_snapshot(&h->quad[j], &sa);
            mc_quad_snapshot(&h->quad[n + j], &sb);
            h->fault_or |= mc_cell_tick(c, &sa, &sb);
            for (int ch = 0; ch < 2; ch++) {
                const mc_drive_out_t *o = &c->out[ch];
                int i = ch * n + j;
                if (o->enable) {
                    /* V = +-duty/top * Vs, held over the tick (the table holds the same quotients) */
                    int32_t top = c->drive.pwm_top;
                    double vlt = (h->volt_tab && top == h->volt_tab_top && o->duty <= top)
                                     ? h->volt_tab[o->duty]
                                     : (double)o->duty / (double)top * h->supply_v;
                    double vs = o->dir ? vlt : -vlt;
                    p->volt[ch][j] = vs;
                    p->mgain[ch][j] = h->kt;
                    if (fast) {
                        mv[i] = h->kt * vs;            /* F = m V (he_plant_forces) */
                        den[i] = den_on[i];
                    }
                } else {
                    p->volt[ch][j] = 0.0;
                    p->mgain[ch][j] = 0.0;
                    if (fast) {
                        mv[i] = 0.0 * 0.0;
                        den[i] = den_off[i];
                    }
                }
            }
        }
        double tk = t0 + (double)k * h->tick_s;
        for (int s = 0; s < h->substeps; s++) {
            double ts = tk + (double)s * dt;
            int rc;
            if (fast && !pert_active(p, ts + HE_STAGE_EDGE * dt)) {
                rc = plant_step_fast(p, dt, mv, den, x, v, bond);
                ts = ts + (double)1 * dt;
            } else {
                rc = he_advance(p, h->stepper, dt, 1, &ts, x, v);
            }
            if (rc != HE_OK) {
                *t = ts;
                return rc;
            }
            if (h->jitter_counts > 0.0 || h->glitch_prob > 0.0) {
                for (int i = 0; i < 2 * n; i++)
                    encoder_feed(h, i, x[i]);
            } else {
                /* noise off: encoder_feed without its random draws, the same steps in the same order */
                const double cpr = h->counts_per_rad;
                for (int i = 0; i < 2 * n; i++) {
                    double c = x[i] * cpr;
                    c = c > 2.0e9 ? 2.0e9 : c;
                    c = c < -2.0e9 ? -2.0e9 : c;
                    int32_t target = (int32_t)c;
                    target -= (double)target > c;
                    int32_t cur = h->count[i];
                    if (cur == target)
                        continue;
                    mc_quad_t *q = &h->quad[i];
                    while (cur != target) {
                        cur += cur < target ? 1 : -1;
                        mc_quad_update(q, (uint8_t)he_gray(cur));
                    }
                    h->count[i] = cur;
                }
            }
        }
        h->ticks++;
    }
    *t = t0 + (double)n_ticks * h->tick_s;
    return HE_OK;
}
