/* Sampled runs: many output samples per C call for the lattice (he_advance) and hil (he_hil_run) loops. */
#ifndef HE_SAMPLE_H
#define HE_SAMPLE_H

#include <stdint.h>
#include "he_plant.h"
#include "he_hil.h"

/*
 * Output sample k (k = 1, 2, ...) of a run with output interval dt_out is the state at t_k = k dt_out.
 * These functions produce samples k0+1 .. k0+nsamp in one call, exactly as the same number of separate
 * per-sample calls would (same arithmetic, same order, so bit-identical results):
 *
 * he_advance_sampled, for s = 0 .. nsamp-1:
 *     *t = (k0 + s) dt_out                                   (time reset per sample: no rounding drift)
 *     he_advance(p, stepper, h, nsub, t, x, v)               (nsub steps of h; state checked at the end)
 *     out[s*2n .. s*2n+2n-1] = x                             (alpha_1..alpha_n, beta_1..beta_n, rad)
 *
 * he_hil_run_sampled, for s = 0 .. nsamp-1:
 *     *t = (tick0 + s ticks_per_out) / rate_hz               (tick0 = control ticks done before the call)
 *     he_hil_run(hl, ticks_per_out, t, x, v)                 (firmware ticks, plant steps, encoders)
 *     out[s*2n .. s*2n+2n-1] = x
 *
 * out holds nsamp * 2n doubles (row-major). *done = samples completed and written. On failure the return
 * value is the HE_ERR_* of the failing sample (checked exactly as in the per-sample call), *t is the time
 * that call reported (end of the failing sample's interval for the lattice, of the failing plant step for
 * the hil), x/v hold its state, and *done = index of the failing sample (rows 0..*done-1 are valid).
 * HE_ERR_ARG (nothing run) for nsamp < 0, a non-positive interval or a null pointer.
 */
int he_advance_sampled(const he_plant_t *p, int stepper, double h, int64_t nsub, double dt_out, int64_t k0,
                       int64_t nsamp, double *t, double *x, double *v, double *out, int64_t *done);
int he_hil_run_sampled(he_hil_t *hl, int64_t tick0, int64_t rate_hz, int64_t ticks_per_out, int64_t nsamp,
                       double *t, double *x, double *v, double *out, int64_t *done);

/*
 * he_hil_run_batch: m independent hil lattices (a sweep's points) in one call. Lattice i runs exactly as
 * he_hil_run_sampled(hl[i], 0, rate_hz[i], tpo[i], nsamp[i], &t, x[i], v[i], out[i], &done[i]) from t = 0
 * would (so bit-identical per lattice), except that out[i] may be NULL: then only the final state is kept
 * (x[i], v[i]). rc[i] = HE_OK or that lattice's HE_ERR_*; a failing lattice does not stop the others.
 * Returns the number of lattices whose rc is not HE_OK (HE_ERR_ARG for m < 0 or a null array).
 */
int he_hil_run_batch(int32_t m, he_hil_t *const *hl, const int64_t *rate_hz, const int64_t *tpo,
                     const int64_t *nsamp, double *const *x, double *const *v, double *const *out,
                     int64_t *done, int32_t *rc);

#endif /* HE_SAMPLE_H */
