/* Dormand-Prince 8(5,3): the fixed-step plant stepper and the adaptive driver with PI step control (equations in he_dop853.h). */
#include <math.h>
#include <stddef.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include "he_dop853.h"

/* ---- the tableau (Hairer's dop853.f; the digits scipy's dop853_coefficients.py carries) ---- */
static const double C2 = 0.526001519587677318785587544488e-01, C3 = 0.789002279381515978178381316732e-01,
                    C4 = 0.118350341907227396726757197510, C5 = 0.281649658092772603273242802490,
                    C6 = 0.333333333333333333333333333333, C7 = 0.25, C8 = 0.307692307692307692307692307692,
                    C9 = 0.651282051282051282051282051282, C10 = 0.6, C11 = 0.857142857142857142857142857142;

/* Stage i (2..12, 1-based as in the paper) = y + h sum_m A_i[m] k_{I_i[m]} (0-based stage indices). */
static const int I2[] = {0};
static const double A2[] = {5.26001519587677318785587544488e-2};
static const int I3[] = {0, 1};
static const double A3[] = {1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2};
static const int I4[] = {0, 2};
static const double A4[] = {2.95875854768068491816892993775e-2, 8.87627564304205475450678981324e-2};
static const int I5[] = {0, 2, 3};
static const double A5[] = {2.41365134159266685502369798665e-1, -8.84549479328286085344864962717e-1,
                            9.24834003261792003115737966543e-1};
static const int I6[] = {0, 3, 4};
static const double A6[] = {3.7037037037037037037037037037e-2, 1.70828608729473871279604482173e-1,
                            1.25467687566822425016691814123e-1};
static const int I7[] = {0, 3, 4, 5};
static const double A7[] = {3.7109375e-2, 1.70252211019544039314978060272e-1, 6.02165389804559606850219397283e-2,
                            -1.7578125e-2};
static const int I8[] = {0, 3, 4, 5, 6};
static const double A8[] = {3.70920001185047927108779319836e-2, 1.70383925712239993810214054705e-1,
                            1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
                            8.27378916381402288758473766002e-3};
static const int I9[] = {0, 3, 4, 5, 6, 7};
static const double A9[] = {6.24110958716075717114429577812e-1, -3.36089262944694129406857109825,
                            -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
                            2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1};
static const int I10[] = {0, 3, 4, 5, 6, 7, 8};
static const double A10[] = {4.77662536438264365890433908527e-1, -2.48811461997166764192642586468,
                             -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
                             1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
                             -2.03312017085086261358222928593e-2};
static const int I11[] = {0, 3, 4, 5, 6, 7, 8, 9};
static const double A11[] = {-9.3714243008598732571704021658e-1, 5.18637242884406370830023853209,
                             1.09143734899672957818500254654, -8.14978701074692612513997267357,
                             -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1,
                             2.49360555267965238987089396762, -3.0467644718982195003823669022};
static const int I12[] = {0, 3, 4, 5, 6, 7, 8, 9, 10};
static const double A12[] = {2.27331014751653820792359768449, -1.05344954667372501984066689879e1,
                             -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
                             2.79488845294199600508499808837e1, -2.85899827713502369474065508674,
                             -8.87285693353062954433549289258, 1.23605671757943030647266201528e1,
                             6.43392746015763530355970484046e-1};
/* weights of the 8th-order solution (stages 1, 6..12) */
static const int IB[] = {0, 5, 6, 7, 8, 9, 10, 11};
static const double B[] = {5.42937341165687622380535766363e-2, 4.45031289275240888144113950566,
                           1.89151789931450038304281599044, -5.8012039600105847814672114227,
                           3.1116436695781989440891606237e-1, -1.52160949662516078556178806805e-1,
                           2.01365400804030348374776537501e-1, 4.47106157277725905176885569043e-2};
/* 5th-order error weights (same stages) and the 3rd-order one's: E3 = B - (bhh1 at 1, bhh2 at 9, bhh3 at 12) */
static const double E5[] = {0.1312004499419488073250102996e-1, -0.1225156446376204440720569753e+1,
                            -0.4957589496572501915214079952, 0.1664377182454986536961530415e+1,
                            -0.3503288487499736816886487290, 0.3341791187130174790297318841,
                            0.8192320648511571246570742613e-1, -0.2235530786388629525884427845e-1};
static const double BHH1 = 0.244094488188976377952755905512, BHH2 = 0.733846688281611857341361741547,
                    BHH3 = 0.220588235294117647058823529412e-1;

/* ---- scratch layout (N = state entries: 4n with inertia, 2n overdamped; n2 = 2n) ----
 * y, y1, ys [N each], k[13 N] (stage 13 = f at y1: the next step's stage 1), F, C, cI = C/I, iI = 1/I [n2 each],
 * then the switch sides at y and at a probe state [nsw bytes each, nsw <= 17n (he_plant_nswitch): within the
 * 3 n2 doubles left] */
typedef struct {
    int n2, N, inertia, nsw;
    double *y, *y1, *ys, *k, *F, *C, *cI, *iI;
    unsigned char *s0, *s1;
} ws_t;

static int ws_bind(const he_plant_t *p, double *work, int64_t len, ws_t *w)
{
    int n2 = 2 * p->n, N = p->inertia ? 2 * n2 : n2;
    if (!work || len < (int64_t)HE_DOP853_WORK_PER_STATE * n2)
        return HE_ERR_NOMEM;
    w->n2 = n2;
    w->N = N;
    w->inertia = p->inertia;
    w->y = work;
    w->y1 = w->y + N;
    w->ys = w->y1 + N;
    w->k = w->ys + N;
    w->F = w->k + 13 * N;
    w->C = w->F + n2;
    w->cI = w->C + n2;
    w->iI = w->cI + n2;
    w->nsw = he_plant_nswitch(p);
    if ((int64_t)2 * w->nsw > (len - (int64_t)(16 * N + 4 * n2)) * (int64_t)sizeof(double))
        return HE_ERR_NOMEM;
    w->s0 = (unsigned char *)(void *)(w->iI + n2);
    w->s1 = w->s0 + w->nsw;
    /* C = eta + m / S_L is fixed while the driver runs (the hil changes m only between its calls) */
    for (int i = 0; i < n2; i++) {
        int ch = i >= p->n, j = i - ch * p->n;
        w->C[i] = he_damping(p, ch, j);
        if (p->inertia) {
            w->iI[i] = 1.0 / p->I[ch];
            w->cI[i] = w->C[i] / p->I[ch];
        }
    }
    return HE_OK;
}

/* k = f(t, y): (v, F/I - (C/I) v) or F/C */
static void deriv(const he_plant_t *p, const ws_t *w, double t, const double *restrict y, double *restrict k)
{
    int n2 = w->n2;
    double *restrict F = w->F;
    he_plant_torques(p, t, y, F);
    if (w->inertia) {
        const double *restrict v = y + n2;
        for (int i = 0; i < n2; i++) {
            k[i] = v[i];
            k[n2 + i] = F[i] * w->iI[i] - w->cI[i] * v[i];
        }
    } else {
        for (int i = 0; i < n2; i++)
            k[i] = F[i] / w->C[i];
    }
}

/* out = y + h sum_q a[q] k_{idx[q]}, inlined at each call with its constant m (the term loop unrolls); two
 * entries per SSE2 instruction where there is SSE2 (each lane the scalar IEEE operations, so the same bits) */
static inline void combine(int N, const double *restrict y, double h, int m, const double *a, const int *idx,
                           const double *restrict k, double *restrict out)
{
    int e = 0;
#ifdef __SSE2__
    const __m128d hv = _mm_set1_pd(h);
    for (; e + 2 <= N; e += 2) {
        __m128d s = _mm_setzero_pd();
        for (int q = 0; q < m; q++)
            s = _mm_add_pd(s, _mm_mul_pd(_mm_set1_pd(a[q]), _mm_loadu_pd(k + idx[q] * N + e)));
        _mm_storeu_pd(out + e, _mm_add_pd(_mm_loadu_pd(y + e), _mm_mul_pd(hv, s)));
    }
#endif
    for (; e < N; e++) {
        double s = 0.0;
        for (int q = 0; q < m; q++)
            s += a[q] * k[idx[q] * N + e];
        out[e] = y[e] + h * s;
    }
}

#define NTERMS(arr) ((int)(sizeof(arr) / sizeof((arr)[0])))

/* Stages 2..12 of a step of size h from (t, y) with k_1 = f(t + e h, y) in k[0..N); y1 = the 8th-order
 * solution. With want_err, returns the error norm of he_dop853.h (NaN or inf when a stage went non-finite),
 * else 0. 11 force evaluations. */
static double dop853_stages(const he_plant_t *p, const ws_t *w, double t, double h, double rtol, double atol,
                            int want_err)
{
    const int N = w->N;
    const double *y = w->y;
    double *k = w->k, *ys = w->ys, *y1 = w->y1;
    combine(N, y, h, NTERMS(A2), A2, I2, k, ys);
    deriv(p, w, t + C2 * h, ys, k + 1 * N);
    combine(N, y, h, NTERMS(A3), A3, I3, k, ys);
    deriv(p, w, t + C3 * h, ys, k + 2 * N);
    combine(N, y, h, NTERMS(A4), A4, I4, k, ys);
    deriv(p, w, t + C4 * h, ys, k + 3 * N);
    combine(N, y, h, NTERMS(A5), A5, I5, k, ys);
    deriv(p, w, t + C5 * h, ys, k + 4 * N);
    combine(N, y, h, NTERMS(A6), A6, I6, k, ys);
    deriv(p, w, t + C6 * h, ys, k + 5 * N);
    combine(N, y, h, NTERMS(A7), A7, I7, k, ys);
    deriv(p, w, t + C7 * h, ys, k + 6 * N);
    combine(N, y, h, NTERMS(A8), A8, I8, k, ys);
    deriv(p, w, t + C8 * h, ys, k + 7 * N);
    combine(N, y, h, NTERMS(A9), A9, I9, k, ys);
    deriv(p, w, t + C9 * h, ys, k + 8 * N);
    combine(N, y, h, NTERMS(A10), A10, I10, k, ys);
    deriv(p, w, t + C10 * h, ys, k + 9 * N);
    combine(N, y, h, NTERMS(A11), A11, I11, k, ys);
    deriv(p, w, t + C11 * h, ys, k + 10 * N);
    combine(N, y, h, NTERMS(A12), A12, I12, k, ys);
    deriv(p, w, t + (1.0 - HE_STAGE_EDGE) * h, ys, k + 11 * N);
    if (!want_err) {
        combine(N, y, h, NTERMS(B), B, IB, k, y1);
        return 0.0;
    }
    double s5 = 0.0, s3 = 0.0;
    for (int e = 0; e < N; e++) {
        double b = 0.0, e5 = 0.0;
        for (int q = 0; q < NTERMS(B); q++) {
            double kq = k[IB[q] * N + e];
            b += B[q] * kq;
            e5 += E5[q] * kq;
        }
        double e3 = b - BHH1 * k[e] - BHH2 * k[8 * N + e] - BHH3 * k[11 * N + e];
        double yn = y[e] + h * b;
        y1[e] = yn;
        double ay = fabs(y[e]), an = fabs(yn);
        double sk = atol + rtol * (ay > an ? ay : an);
        e5 /= sk;
        e3 /= sk;
        s5 += e5 * e5;
        s3 += e3 * e3;
    }
    double den = s5 + 0.01 * s3;
    if (!(den > 0.0))
        return den == 0.0 ? 0.0 : NAN;
    return fabs(h) * s5 / sqrt((double)N * den);
}

static void load_state(const ws_t *w, const double *x, const double *v)
{
    memcpy(w->y, x, (size_t)w->n2 * sizeof(double));
    if (w->inertia)
        memcpy(w->y + w->n2, v, (size_t)w->n2 * sizeof(double));
}

static int same_state(const ws_t *w, const double *x, const double *v)
{
    return memcmp(w->y, x, (size_t)w->n2 * sizeof(double)) == 0
        && (!w->inertia || memcmp(w->y + w->n2, v, (size_t)w->n2 * sizeof(double)) == 0);
}

/* x, v of y (overdamped: v = F/C at y, which k holds) */
static void store_state(const ws_t *w, const double *k, double *x, double *v)
{
    memcpy(x, w->y, (size_t)w->n2 * sizeof(double));
    memcpy(v, w->inertia ? w->y + w->n2 : k, (size_t)w->n2 * sizeof(double));
}

/* flush |y_i| < HE_TINY_RAD to 0, as every stepper does after a step (subnormals are slow) */
static void flush_tiny(int N, double *y)
{
    for (int e = 0; e < N; e++)
        y[e] = fabs(y[e]) < HE_TINY_RAD ? 0.0 : y[e];
}

/* ---- fixed steps (he_advance) ---- */
double he_dop853_limit(const he_plant_t *p, int stepper, int *limiting_chain)
{
    double w2[2], cmin[2], cmax[2], rate[2], best = INFINITY;
    int arg = -1;
    if (stepper != HE_STEP_DOP853)
        return -1.0;
    he_plant_bounds(p, w2, cmin, cmax, rate);
    for (int ch = 0; ch < 2; ch++) {
        double h = INFINITY;
        if (!p->inertia) {
            if (rate[ch] > 0.0)
                h = 6.0 / rate[ch];
        } else {
            double m = sqrt(w2[ch]) > cmax[ch] ? sqrt(w2[ch]) : cmax[ch];
            if (m > 0.0)
                h = (double)HE_DOP853_LIMIT_X1000 / 1000.0 / m;
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

int he_dop853_advance(const he_plant_t *p, int stepper, double h, int64_t nsteps, double t0, double *x,
                      double *v, double *work)
{
    ws_t w;
    (void)stepper;
    int rc = ws_bind(p, work, (int64_t)HE_WORK_PER_STATE * 2 * p->n, &w);
    if (rc != HE_OK)
        return rc;
    load_state(&w, x, v);
    for (int64_t s = 0; s < nsteps; s++) {
        double t = t0 + (double)s * h;    /* no accumulated rounding in t */
        deriv(p, &w, t + HE_STAGE_EDGE * h, w.y, w.k);
        dop853_stages(p, &w, t, h, 0.0, 1.0, 0);
        flush_tiny(w.N, w.y1);
        memcpy(w.y, w.y1, (size_t)w.N * sizeof(double));
    }
    if (!w.inertia)
        deriv(p, &w, t0 + (double)nsteps * h, w.y, w.k);   /* v = F/C at the final state */
    store_state(&w, w.k, x, v);
    return HE_OK;
}

/* ---- the adaptive driver ---- */
int he_dop853_init(he_dop853_t *a, double rtol, double atol, double h_max, double *work, int64_t work_len)
{
    if (!a || !(rtol >= 0.0) || !isfinite(rtol) || !(atol > 0.0) || !isfinite(atol) || !(h_max > 0.0) || !work
        || work_len < 0)
        return HE_ERR_ARG;
    memset(a, 0, sizeof(*a));
    a->rtol = rtol;
    a->atol = atol;
    a->h_max = h_max;
    a->h_min = 1e-12;
    a->err_old = 1e-4;
    a->land = 1;
    a->work = work;
    a->work_len = work_len;
    return HE_OK;
}

/* 1 when every perturbation is on at both times or off at both */
static int same_forcing(const he_plant_t *p, double ta, double tb)
{
    for (int i = 0; i < p->npert; i++) {
        int on_a = ta >= p->pert[i].t0 && ta < p->pert[i].t1;
        int on_b = tb >= p->pert[i].t0 && tb < p->pert[i].t1;
        if (on_a != on_b)
            return 0;
    }
    return 1;
}

static double norm_rms(int N, const double *y, const double *z, double rtol, double atol)
{
    double s = 0.0;
    for (int e = 0; e < N; e++) {
        double sk = atol + rtol * fabs(y[e]);
        s += (z[e] / sk) * (z[e] / sk);
    }
    return sqrt(s / (double)N);
}

/* Hairer's starting step (Solving ODE I, II.4): from |y0|, |f0| and a difference quotient of f; 1 evaluation. */
static double initial_step(const he_plant_t *p, const ws_t *w, double t, double rtol, double atol, double hmax)
{
    const int N = w->N;
    double d0 = norm_rms(N, w->y, w->y, rtol, atol), d1 = norm_rms(N, w->y, w->k, rtol, atol);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h0 = h0 < hmax ? h0 : hmax;
    for (int e = 0; e < N; e++)
        w->ys[e] = w->y[e] + h0 * w->k[e];
    double *f1 = w->k + 12 * N;
    deriv(p, w, t + h0, w->ys, f1);
    for (int e = 0; e < N; e++)
        w->y1[e] = f1[e] - w->k[e];
    double d2 = norm_rms(N, w->y, w->y1, rtol, atol) / h0;
    double dm = d1 > d2 ? d1 : d2;
    double h1 = dm <= 1e-15 ? (h0 * 1e-3 > 1e-6 ? h0 * 1e-3 : 1e-6) : pow(0.01 / dm, 1.0 / 8.0);
    double h = 100.0 * h0 < h1 ? 100.0 * h0 : h1;
    return h < hmax ? h : hmax;
}

/* Where in the step (0..1) the first switch of w->s0 changes side: bisection on the cubic Hermite interpolant of
 * x between y and y1 (slopes v, or F/C of stages 1 and 12 overdamped), HE_DOP853_LOCATE_ITER halvings; returns
 * the lower end, where every side is still that of y. Uses w->ys and w->s1 as scratch. */
static double locate_switch(const he_plant_t *p, const ws_t *w, double h)
{
    const int n2 = w->n2;
    const double *x0 = w->y, *x1 = w->y1;
    const double *d0 = w->inertia ? w->y + n2 : w->k, *d1 = w->inertia ? w->y1 + n2 : w->k + 11 * w->N;
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < HE_DOP853_LOCATE_ITER; it++) {
        double th = 0.5 * (lo + hi), t2 = th * th, t3 = t2 * th;
        double h00 = 2.0 * t3 - 3.0 * t2 + 1.0, h10 = (t3 - 2.0 * t2 + th) * h, h01 = 3.0 * t2 - 2.0 * t3,
               h11 = (t3 - t2) * h;
        for (int i = 0; i < n2; i++)
            w->ys[i] = h00 * x0[i] + h10 * d0[i] + h01 * x1[i] + h11 * d1[i];
        he_plant_switches(p, w->ys, w->s1);
        if (memcmp(w->s0, w->s1, (size_t)w->nsw) != 0)
            hi = th;
        else
            lo = th;
    }
    return lo;
}

int he_dop853_run(const he_plant_t *p, he_dop853_t *a, double t0, double t1, double *x, double *v,
                  double *t_fail)
{
    if (!p || !a || !x || !v || !(t1 > t0) || !isfinite(t0) || !isfinite(t1) || p->n < 1 || p->n > HE_MAX_CELLS)
        return HE_ERR_ARG;
    ws_t w;
    int rc = ws_bind(p, a->work, a->work_len, &w);
    if (rc != HE_OK)
        return rc;
    const int N = w.N;
    const double expo = 1.0 / 8.0 - 0.2 * HE_DOP853_BETA;
    double *k1 = w.k, *k13 = w.k + 12 * N;
    /* the stored f(t, y) serves again only for the very state and time it was taken at, on the same forcing */
    if (!(a->fsal && t0 == a->t_end && same_state(&w, x, v) && same_forcing(p, a->t_fsal, t0))) {
        load_state(&w, x, v);
        deriv(p, &w, t0, w.y, k1);     /* stage 1 (at t0: the forcing is the same on [t0, t1)) */
        a->t_fsal = t0;
        a->nfev++;
    }
    a->fsal = 0;
    if (!(a->h > 0.0)) {
        a->h = initial_step(p, &w, t0, a->rtol, a->atol, a->h_max);
        a->nfev++;
    }
    if (!a->land)
        w.nsw = 0;                              /* switches ignored: every step judged by its error alone */
    if (w.nsw)
        he_plant_switches(p, w.y, w.s0);
    double t = t0, h_land = 0.0;
    int nonfinite = 0;                          /* the last rejected attempt went non-finite */
    while (t < t1) {
        double h = a->h < a->h_max ? a->h : a->h_max;
        double left = t1 - t;
        int last = 0, landing = h_land > 0.0;
        if (landing) {
            h = h_land;                         /* up to the switch the last attempt crossed */
            h_land = 0.0;
        } else if (h * HE_DOP853_STRETCH >= left) {
            h = left;                           /* the last step (stretched by up to 5 %) */
            last = 1;
        } else if (2.0 * h > left) {
            h = 0.5 * left;                     /* two equal steps instead of a long and a sliver */
        }
        if (!last && (!(h >= a->h_min) || t + h == t)) {
            if (t_fail)
                *t_fail = t;
            return nonfinite ? HE_ERR_NONFINITE : HE_ERR_TOL;
        }
        double err = dop853_stages(p, &w, t, h, a->rtol, a->atol, 1);
        a->nfev += 11;
        if (err <= 1.0 && w.nsw) {
            /* a step across a switch of the force law (a kink: its error estimate cannot be trusted) is redone
             * up to the switch, unless the switch lies within HE_DOP853_SWITCH_EPS of either end */
            he_plant_switches(p, w.y1, w.s1);
            if (memcmp(w.s0, w.s1, (size_t)w.nsw) != 0) {
                double th = locate_switch(p, &w, h);
                if (th > HE_DOP853_SWITCH_EPS && th < 1.0 - HE_DOP853_SWITCH_EPS) {
                    h_land = th * h;
                    a->landings++;
                    continue;
                }
                he_plant_switches(p, w.y1, w.s1);
            }
        }
        if (err <= 1.0) {
            double g = HE_DOP853_SAFE * pow(err > 1e-300 ? err : 1e-300, -expo) * pow(a->err_old, HE_DOP853_BETA);
            g = g < 1.0 / 3.0 ? 1.0 / 3.0 : (g > 6.0 ? 6.0 : g);
            if (a->rejected && g > 1.0)
                g = 1.0;
            a->err_old = err > 1e-4 ? err : 1e-4;
            a->rejected = 0;
            a->steps++;
            flush_tiny(N, w.y1);
            double tn = last ? t1 : t + h;
            deriv(p, &w, t + (1.0 - HE_STAGE_EDGE) * h, w.y1, k13);   /* f at the new state: the next stage 1 */
            a->nfev++;
            a->t_fsal = t + (1.0 - HE_STAGE_EDGE) * h;
            memcpy(w.y, w.y1, (size_t)N * sizeof(double));
            memcpy(k1, k13, (size_t)N * sizeof(double));
            if (w.nsw)
                memcpy(w.s0, w.s1, (size_t)w.nsw);
            /* a step cut short to land on t1 or on a switch proposes no less than the step control wanted before */
            double hn = h * g;
            a->h = ((last || landing) && hn < a->h && g >= 1.0) ? a->h : hn;
            t = tn;
        } else {
            nonfinite = !isfinite(err);
            double g = nonfinite ? 0.1 : HE_DOP853_SAFE * pow(err, -expo);
            a->h = h * (nonfinite || g > 1.0 / 3.0 ? g : 1.0 / 3.0);
            a->rejected = 1;
            a->rejects++;
        }
    }
    store_state(&w, k1, x, v);
    rc = he_state_check(w.n2, x, v);
    if (rc == HE_OK)
        rc = he_plant_range_check(p, x, NULL);
    if (rc != HE_OK) {
        if (t_fail)
            *t_fail = t1;
        return rc;
    }
    a->fsal = 1;
    a->t_end = t1;
    return HE_OK;
}

int he_dop853_sampled(const he_plant_t *p, he_dop853_t *a, double dt_out, int64_t k0, int64_t nsamp, double *t,
                      double *x, double *v, double *out, int64_t *done)
{
    if (!p || !a || !t || !x || !v || !out || !done || nsamp < 0 || !(dt_out > 0.0) || k0 < 0)
        return HE_ERR_ARG;
    int n2 = 2 * p->n;
    *done = 0;
    for (int64_t s = 0; s < nsamp; s++) {
        double ta = (double)(k0 + s) * dt_out, tb = (double)(k0 + s + 1) * dt_out;
        *t = ta;
        while (*t < tb) {
            /* the next perturbation edge inside (t, tb), else tb */
            double te = tb;
            for (int i = 0; i < p->npert; i++) {
                double e0 = p->pert[i].t0, e1 = p->pert[i].t1;
                te = (e0 > *t && e0 < te) ? e0 : te;
                te = (e1 > *t && e1 < te) ? e1 : te;
            }
            double tf = te;
            int rc = he_dop853_run(p, a, *t, te, x, v, &tf);
            if (rc != HE_OK) {
                *t = tf;
                return rc;
            }
            *t = te;
        }
        memcpy(out + s * n2, x, (size_t)n2 * sizeof(double));
        *done = s + 1;
    }
    return HE_OK;
}
