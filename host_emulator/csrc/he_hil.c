/* Closed loop of the compiled cell firmware with the plant (equations in he_hil.h). */
#include <math.h>
#include "he_hil.h"
#include "he_step.h"

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

int32_t he_encoder_feed(he_hil_t *h, int i, double theta)
{
    double c = theta * h->counts_per_rad;
    if (h->jitter_counts > 0.0)
        c += h->jitter_counts * gauss(h);
    if (c > 2.0e9)
        c = 2.0e9;
    if (c < -2.0e9)
        c = -2.0e9;
    int32_t target = (int32_t)floor(c);
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

void he_hil_sync_encoders(he_hil_t *h, const double *x)
{
    for (int i = 0; i < 2 * h->n; i++) {
        int32_t c = (int32_t)floor(x[i] * h->counts_per_rad);
        h->count[i] = c;
        mc_quad_init(&h->quad[i], (uint8_t)he_gray(c));
        mc_quad_set_pos(&h->quad[i], c);
    }
}

int he_hil_run(he_hil_t *h, int64_t n_ticks, double *t, double *x, double *v)
{
    he_plant_t *p = h->plant;
    int n = h->n;
    if (!p || n != p->n || h->substeps < 1 || !(h->tick_s > 0.0))
        return HE_ERR_ARG;
    double dt = h->tick_s / h->substeps;
    double t0 = *t;
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
                if (o->enable) {
                    /* V = +-duty/top * Vs, held over the tick */
                    double vlt = (double)o->duty / (double)c->drive.pwm_top * h->supply_v;
                    p->volt[ch][j] = o->dir ? vlt : -vlt;
                    p->mgain[ch][j] = h->kt;
                } else {
                    p->volt[ch][j] = 0.0;
                    p->mgain[ch][j] = 0.0;
                }
            }
        }
        double tk = t0 + (double)k * h->tick_s;
        for (int s = 0; s < h->substeps; s++) {
            double ts = tk + (double)s * dt;
            int rc = he_advance(p, h->stepper, dt, 1, &ts, x, v);
            if (rc != HE_OK) {
                *t = ts;
                return rc;
            }
            for (int i = 0; i < 2 * n; i++)
                he_encoder_feed(h, i, x[i]);
        }
        h->ticks++;
    }
    *t = t0 + (double)n_ticks * h->tick_s;
    return HE_OK;
}
