/* The cubic small-angle band law on bond differences: one definition for the plant's kernels and hil's fast step. */
#ifndef HE_BAND_H
#define HE_BAND_H
#ifndef MC_CDEF /* internal to the C (inline helpers): nothing here is the FFI's */

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include "he_plant.h"

/*
 * A bond's two bands with the cubic law g(d) = c0 + d (c1 + d (c2 + d c3)) for d > 0 (a slack band: `slack`, c0 when
 * the law keeps its f0, else 0), at stretch d0 +- u, u = L (x_i - x_k) the lever times the bond's angle difference:
 *   he_band_diff(u) = g(d0 + u) - g(d0 - u)
 * The caller multiplies by its own factor (k_b * band_scale * L). The SSE2 form does each lane's scalar IEEE
 * operations in the same order, so every caller keeps every bit whichever form runs.
 */
typedef struct {
    double d0, c0, c1, c2, c3, slack;
} he_band_law_t;

/* Chain ch's law from the plant (its cubic fit, delta0 and whether a slack band keeps f0). */
static inline he_band_law_t he_band_law(const he_plant_t *p, int ch)
{
    const double *c = p->coef[ch];
    he_band_law_t k = {p->delta0[ch], c[0], c[1], c[2], c[3], p->slack_f0 ? c[0] : 0.0};
    return k;
}

static inline double he_band_diff(const he_band_law_t *k, double u)
{
    double dp = k->d0 + u, dm = k->d0 - u;
    double gp = k->c0 + dp * (k->c1 + dp * (k->c2 + dp * k->c3));
    double gm = k->c0 + dm * (k->c1 + dm * (k->c2 + dm * k->c3));
    gp = dp > 0.0 ? gp : k->slack;
    gm = dm > 0.0 ? gm : k->slack;
    return gp - gm;
}

#ifdef __SSE2__
/* The law's constants in both lanes, loaded once before a loop. */
typedef struct {
    __m128d d0, c0, c1, c2, c3, slack, zero;
} he_band_law2_t;

static inline he_band_law2_t he_band_law2(const he_band_law_t *k)
{
    he_band_law2_t v = {_mm_set1_pd(k->d0), _mm_set1_pd(k->c0), _mm_set1_pd(k->c1), _mm_set1_pd(k->c2),
                        _mm_set1_pd(k->c3), _mm_set1_pd(k->slack), _mm_setzero_pd()};
    return v;
}

/* he_band_diff of two bonds at once. */
static inline __m128d he_band_diff2(const he_band_law2_t *k, __m128d u)
{
    __m128d dp = _mm_add_pd(k->d0, u), dm = _mm_sub_pd(k->d0, u);
    __m128d gp = _mm_add_pd(k->c0, _mm_mul_pd(dp, _mm_add_pd(k->c1, _mm_mul_pd(dp, _mm_add_pd(k->c2, _mm_mul_pd(dp, k->c3))))));
    __m128d gm = _mm_add_pd(k->c0, _mm_mul_pd(dm, _mm_add_pd(k->c1, _mm_mul_pd(dm, _mm_add_pd(k->c2, _mm_mul_pd(dm, k->c3))))));
    __m128d mp = _mm_cmpgt_pd(dp, k->zero), mm = _mm_cmpgt_pd(dm, k->zero);
    gp = _mm_or_pd(_mm_and_pd(mp, gp), _mm_andnot_pd(mp, k->slack));
    gm = _mm_or_pd(_mm_and_pd(mm, gm), _mm_andnot_pd(mm, k->slack));
    return _mm_sub_pd(gp, gm);
}
#endif

#endif /* MC_CDEF */
#endif /* HE_BAND_H */
