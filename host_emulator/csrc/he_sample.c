/* Sampled lattice and hil runs: per-sample he_advance / he_hil_run calls in one C loop (contract in he_sample.h). */
#include <stddef.h>
#include <string.h>
#include "he_sample.h"
#include "he_step.h"

static void record(double *row, const double *x, int n2)
{
    memcpy(row, x, (size_t)n2 * sizeof(double));
}

int he_advance_sampled(const he_plant_t *p, int stepper, double h, int64_t nsub, double dt_out, int64_t k0,
                       int64_t nsamp, double *t, double *x, double *v, double *out, int64_t *done)
{
    if (!p || !t || !x || !v || !out || !done || nsamp < 0 || !(dt_out > 0.0) || k0 < 0)
        return HE_ERR_ARG;
    int n2 = 2 * p->n;
    *done = 0;
    for (int64_t s = 0; s < nsamp; s++) {
        *t = (double)(k0 + s) * dt_out;               /* t_{k-1} = (k - 1) dt_out, k = k0 + s + 1 */
        int rc = he_advance(p, stepper, h, nsub, t, x, v);
        if (rc != HE_OK)
            return rc;                                /* *t: as he_advance left it */
        record(out + s * n2, x, n2);
        *done = s + 1;
    }
    return HE_OK;
}

int he_hil_run_sampled(he_hil_t *hl, int64_t tick0, int64_t rate_hz, int64_t ticks_per_out, int64_t nsamp,
                       double *t, double *x, double *v, double *out, int64_t *done)
{
    if (!hl || !hl->plant || !t || !x || !v || !out || !done || nsamp < 0 || rate_hz < 1 || ticks_per_out < 1
        || tick0 < 0)
        return HE_ERR_ARG;
    int n2 = 2 * hl->n;
    *done = 0;
    if (nsamp == 0)
        return HE_OK;
    he_hil_ws_t *w;                                   /* one scratch for every sample (heap, he_hil.h) */
    int rc = he_hil_ws_open(hl, &w);
    for (int64_t s = 0; s < nsamp && rc == HE_OK; s++) {
        /* t = tick / rate_hz, both exact in a double: the correctly rounded quotient, as Python's int / int */
        *t = (double)(tick0 + s * ticks_per_out) / (double)rate_hz;
        rc = he_hil_run_ws(w, ticks_per_out, t, x, v);
        if (rc != HE_OK)
            break;                                    /* *t: as he_hil_run left it */
        record(out + s * n2, x, n2);
        *done = s + 1;
    }
    he_hil_ws_close(w);
    return rc;
}

int he_hil_run_batch(int32_t m, he_hil_t *const *hl, const int64_t *rate_hz, const int64_t *tpo,
                     const int64_t *nsamp, double *const *x, double *const *v, double *const *out,
                     int64_t *done, int32_t *rc)
{
    if (m < 0 || (m > 0 && (!hl || !rate_hz || !tpo || !nsamp || !x || !v || !out || !done || !rc)))
        return HE_ERR_ARG;
    int failed = 0;
    for (int32_t i = 0; i < m; i++) {
        done[i] = 0;
        if (!hl[i] || !hl[i]->plant || !x[i] || !v[i] || nsamp[i] < 0 || rate_hz[i] < 1 || tpo[i] < 1) {
            rc[i] = HE_ERR_ARG;
            failed++;
            continue;
        }
        int n2 = 2 * hl[i]->n, r = HE_OK;
        he_hil_ws_t *w = NULL;                        /* one scratch per lattice (heap, he_hil.h) */
        if (nsamp[i] > 0)
            r = he_hil_ws_open(hl[i], &w);
        for (int64_t s = 0; s < nsamp[i] && r == HE_OK; s++) {
            double t = (double)(s * tpo[i]) / (double)rate_hz[i];    /* as he_hil_run_sampled, tick0 = 0 */
            r = he_hil_run_ws(w, tpo[i], &t, x[i], v[i]);
            if (r != HE_OK)
                break;
            if (out[i])
                record(out[i] + s * n2, x[i], n2);
            done[i] = s + 1;
        }
        he_hil_ws_close(w);
        rc[i] = r;
        failed += r != HE_OK;
    }
    return failed;
}
