/* Hardware-in-the-loop lattice: compiled cell firmware + motor/driver + quadrature encoders around the plant. */
#ifndef HE_HIL_H
#define HE_HIL_H

#include <stdint.h>
#include "he_plant.h"

#ifndef MC_CDEF /* the FFI pass sees mc_cell.h earlier in the same umbrella */
#include "mc_cell.h"
#endif

/*
 * One control tick k (period tick_s) of every cell j:
 *   snap  = mc_quad_snapshot(enc alpha_j), mc_quad_snapshot(enc beta_j)
 *   mc_cell_tick(cell_j, snap_a, snap_b)  -> out[ch] = {duty, dir, enable}
 *   V_ch  = (dir ? +1 : -1) * duty/pwm_top * supply_v    (PWM averaged, zero-order hold)
 *   m_ch  = enable ? Kt : 0                               (nSLEEP low: coast, no torque)
 * then `substeps` plant steps of h = tick_s/substeps with motor torque
 *   tau_m = m_ch * (V_ch - omega/S_L)
 * and after each plant step every encoder is brought to
 *   c = floor(theta * 400/(2 pi) + jitter),  jitter ~ N(0, jitter_counts^2)
 * by feeding mc_quad_update() every intermediate Gray state (00,01,11,10 for
 * counts 0,1,2,3 mod 4), one per count: no step is ever skipped. A glitch
 * (probability glitch_prob per encoder per plant step) feeds the two illegal
 * transitions ab -> ab^3 -> ab, as a noise spike on both channels would.
 */
typedef struct {
    int32_t n;              /* cells */
    int32_t substeps;       /* plant steps per control tick, >= 1 */
    int32_t stepper;        /* HE_STEP_* */
    double tick_s;          /* control period, s */
    double supply_v;        /* motor supply, V */
    double kt;              /* motor torque constant, N m/V */
    double counts_per_rad;  /* 400 / (2 pi) */
    double jitter_counts;   /* encoder jitter std dev, counts (0 = off) */
    double glitch_prob;     /* per encoder per plant step */
    uint64_t rng;           /* xorshift64* state (nonzero) */
    int64_t ticks;          /* control ticks done */
    uint32_t fault_or;      /* OR of every fault flag returned by the cells */
    uint32_t glitches;      /* glitches injected */
    he_plant_t *plant;
    mc_cell_t *cells;       /* [n] */
    mc_quad_t *quad;        /* [2n]: alpha_j at j, beta_j at n + j */
    int32_t *count;         /* [2n]: count last fed to each decoder */
    const double *volt_tab; /* optional [volt_tab_top + 1]: duty/top * supply_v by duty (he_hil_volt_table) */
    int32_t volt_tab_top;   /* the pwm_top the table was made for */
} he_hil_t;

/* Gray-code (A<<1)|B of an encoder count. */
int he_gray(int32_t count);
/* Quantise (with jitter) and feed every intermediate state; returns the new count. */
int32_t he_encoder_feed(he_hil_t *h, int i, double theta);
/* Set every encoder to the counts of x and its decoder to the matching state. */
void he_hil_sync_encoders(he_hil_t *h, const double *x);
/* tab[d] = d/top * supply_v for d = 0..top: the motor voltage of each duty, as the tick computes it. */
void he_hil_volt_table(double *tab, int32_t top, double supply_v);
/* Run n_ticks control ticks from *t; HE_OK or an HE_ERR_* of the plant state (HE_ERR_NOMEM: no memory for
 * the scratch arrays, nothing run). */
int he_hil_run(he_hil_t *h, int64_t n_ticks, double *t, double *x, double *v);

/* he_hil_run in pieces with one scratch for all of them (the sampled and batch loops, he_sample.h):
 * he_hil_ws_open sets up the per-cylinder arrays (heap, 2n doubles each) from h and its plant, which must not
 * change until he_hil_ws_close; then each he_hil_run_ws(w, n_ticks, t, x, v) does exactly what
 * he_hil_run(h, n_ticks, t, x, v) would. HE_ERR_ARG (and *w = NULL) for an inconsistent h, HE_ERR_NOMEM when
 * malloc fails. he_hil_ws_close(NULL) does nothing. */
typedef struct he_hil_ws he_hil_ws_t;
int he_hil_ws_open(he_hil_t *h, he_hil_ws_t **w);
int he_hil_run_ws(he_hil_ws_t *w, int64_t n_ticks, double *t, double *x, double *v);
void he_hil_ws_close(he_hil_ws_t *w);

#endif /* HE_HIL_H */
