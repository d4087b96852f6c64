/* Golden-vector program: the same inputs through every library entry point, on any build. */
#include "mc_vectors.h"
#include "mc_cell.h"

/* Entry-point types (the library headers are the single source of truth; these
 * must match them, which the compiler checks in mcv_check_types below). */
typedef int (*f_set_raw)(mc_reaction_t *, int32_t, int32_t, int32_t, int32_t, int32_t);
typedef int (*f_from_phys)(mc_reaction_t *, const mc_reaction_phys_t *);
typedef void (*f_eval)(const mc_reaction_t *, int32_t, int32_t, int32_t *, int32_t *);
typedef int32_t (*f_psi)(const mc_reaction_t *, int32_t);
typedef void (*f_drv_default)(mc_drive_config_t *);
typedef int (*f_drv_conf)(mc_drive_t *, const mc_drive_config_t *);
typedef int32_t (*f_drv_limit)(mc_drive_t *, int32_t);
typedef void (*f_drv_cmd)(const mc_drive_t *, int32_t, int32_t, int, mc_drive_out_t *);
typedef void (*f_q_init)(mc_quad_t *, uint8_t);
typedef void (*f_q_update)(mc_quad_t *, uint8_t);
typedef void (*f_q_snap)(const mc_quad_t *, mc_quad_snap_t *);
typedef void (*f_q_setpos)(mc_quad_t *, int32_t);
typedef void (*f_c_defp)(mc_reaction_phys_t *);
typedef void (*f_c_init)(mc_cell_t *);
typedef int (*f_c_setp)(mc_cell_t *, const mc_reaction_phys_t *);
typedef int (*f_c_setd)(mc_cell_t *, const mc_drive_config_t *);
typedef int (*f_c_runaway)(mc_cell_t *, int32_t);
typedef void (*f_c_flag)(mc_cell_t *, int);
typedef int (*f_c_perturb)(mc_cell_t *, int, int32_t, uint32_t);
typedef void (*f_c_zero)(mc_cell_t *, int32_t, int32_t);
typedef void (*f_c_void)(mc_cell_t *);
typedef uint16_t (*f_c_tick)(mc_cell_t *, const mc_quad_snap_t *, const mc_quad_snap_t *);

#ifndef MCV_NO_TYPECHECK
/* Compile-time check that the typedefs above match the library prototypes
 * (the host build reaches the library only through the table: no symbols). */
void mcv_check_types(void);
void mcv_check_types(void)
{
    f_set_raw a1 = mc_reaction_set_raw; f_from_phys a2 = mc_reaction_from_phys;
    f_eval a3 = mc_reaction_eval; f_psi a4 = mc_psi_prime;
    f_drv_default a5 = mc_drive_default_config; f_drv_conf a6 = mc_drive_configure;
    f_drv_limit a7 = mc_drive_set_limit;
    f_drv_cmd a9 = mc_drive_command; f_q_init b1 = mc_quad_init;
    f_q_update b2 = mc_quad_update; f_q_snap b3 = mc_quad_snapshot;
    f_q_setpos b4 = mc_quad_set_pos; f_c_defp b5 = mc_cell_default_params;
    f_c_init b6 = mc_cell_init; f_c_setp b7 = mc_cell_set_params;
    f_c_setd b8 = mc_cell_set_drive; f_c_runaway b9 = mc_cell_set_runaway;
    f_c_flag c1 = mc_cell_enable; f_c_flag c2 = mc_cell_set_bemf;
    f_c_perturb c3 = mc_cell_perturb; f_c_zero c4 = mc_cell_zero;
    f_c_void c5 = mc_cell_clear_faults; f_c_void c6 = mc_cell_report_driver_fault;
    f_c_tick c7 = mc_cell_tick;
    (void)a1; (void)a2; (void)a3; (void)a4; (void)a5; (void)a6; (void)a7;
    (void)a9; (void)b1; (void)b2; (void)b3; (void)b4; (void)b5; (void)b6; (void)b7;
    (void)b8; (void)b9; (void)c1; (void)c2; (void)c3; (void)c4; (void)c5; (void)c6;
    (void)c7;
}
#endif

#define FN(api, name, type) ((type)(api)->fn[MCV_FN_##name])

/* ---- PRNG and input distributions ------------------------------------ */

uint32_t mcv_xorshift32(uint32_t *state)
{
    uint32_t x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    return x;
}

typedef struct {
    uint32_t s;
} rng_t;

static uint32_t rnd(rng_t *g) { return mcv_xorshift32(&g->s); }

/* two's complement view of a word (GCC/Clang define the conversion modulo 2^32) */
static int32_t as_i32(uint32_t w) { return (int32_t)w; }

/* uniform in [lo, hi] (hi >= lo) by multiply-high: no division anywhere */
static int32_t r_range(rng_t *g, int32_t lo, int32_t hi)
{
    uint32_t span = (uint32_t)hi - (uint32_t)lo + 1u;
    uint32_t r = rnd(g);
    if (span == 0u)
        return as_i32(r);
    uint32_t off = (uint32_t)(((uint64_t)r * span) >> 32);
    return as_i32((uint32_t)lo + off);
}

static const int32_t edge_values[] = {
    INT32_MIN, INT32_MIN + 1, -1073741824, -4194305, -4194304, -65536, -2049,
    -2048, -2047, -1025, -1024, -1023, -801, -800, -2, -1, 0, 1, 2, 800, 801,
    1023, 1024, 1025, 2047, 2048, 2049, 65536, 4194304, 4194305, 1073741824,
    INT32_MAX - 1, INT32_MAX,
};
#define N_EDGES ((int32_t)(sizeof(edge_values) / sizeof(edge_values[0])))

/* mostly within +-near, sometimes 4x beyond, an edge value, or any int32 */
static int32_t r_wide(rng_t *g, int32_t near)
{
    switch (rnd(g) & 7u) {
    case 0: return as_i32(rnd(g));
    case 1: return edge_values[r_range(g, 0, N_EDGES - 1)];
    case 2: return r_range(g, -4 * near, 4 * near);
    default: return r_range(g, -near, near);
    }
}

/* a parameter field: mostly valid [lo, hi], sometimes a limit, just outside, or any */
static int32_t r_field(rng_t *g, int32_t lo, int32_t hi)
{
    switch (rnd(g) & 15u) {
    case 10: return lo;
    case 11: return hi;
    case 12: return lo - 1;
    case 13: return hi + 1;
    case 14: return as_i32(rnd(g));
    case 15: return edge_values[r_range(g, 0, N_EDGES - 1)];
    default: return r_range(g, lo, hi);
    }
}

static int32_t sat_add(int32_t a, int32_t b)
{
    int64_t s = (int64_t)a + b;
    return s > INT32_MAX ? INT32_MAX : (s < INT32_MIN ? INT32_MIN : (int32_t)s);
}

static int bytes_equal(const void *a, const void *b, uint32_t n)
{
    const uint8_t *x = (const uint8_t *)a, *y = (const uint8_t *)b;
    for (uint32_t i = 0; i < n; i++)
        if (x[i] != y[i])
            return 0;
    return 1;
}

static void bytes_copy(void *dst, const void *src, uint32_t n)
{
    uint8_t *d = (uint8_t *)dst;
    const uint8_t *s = (const uint8_t *)src;
    for (uint32_t i = 0; i < n; i++)
        d[i] = s[i];
}

/* ---- sink ------------------------------------------------------------- */

void mcv_sink_init(mcv_sink_t *s, uint32_t *data, uint32_t cap_words)
{
    s->data = data;
    s->cap_words = cap_words;
    s->n_words = 0;
    s->n_records = 0;
    s->fnv = 2166136261u;
    s->overflow = 0;
    s->flush = 0;
    for (int i = 0; i < 8; i++) {
        s->fam_fnv[i] = 2166136261u;
        s->fam_count[i] = 0;
    }
}

static void emit(mcv_sink_t *s, const uint32_t rec[MCV_WORDS])
{
    uint32_t fam = (rec[0] >> 24) & 7u;
    for (int i = 0; i < MCV_WORDS; i++) {
        uint32_t w = rec[i];
        for (int b = 0; b < 4; b++) { /* FNV-1a over the little-endian bytes */
            uint32_t byte = (w >> (8 * b)) & 0xffu;
            s->fnv = (s->fnv ^ byte) * 16777619u;
            s->fam_fnv[fam] = (s->fam_fnv[fam] ^ byte) * 16777619u;
        }
    }
    s->fam_count[fam]++;
    if (s->n_words + MCV_WORDS > s->cap_words && s->flush)
        s->flush(s);
    if (s->n_words + MCV_WORDS > s->cap_words) {
        s->overflow = 1;
    } else {
        for (int i = 0; i < MCV_WORDS; i++)
            s->data[s->n_words + (uint32_t)i] = rec[i];
        s->n_words += MCV_WORDS;
    }
    s->n_records++;
}

static void rec_clear(uint32_t rec[MCV_WORDS], uint32_t fam, uint32_t sub, uint32_t idx)
{
    for (int i = 0; i < MCV_WORDS; i++)
        rec[i] = 0;
    rec[0] = (fam << 24) | ((sub & 0xffu) << 16) | (idx & 0xffffu);
}

#define W(x) ((uint32_t)(x))

/* ---- families --------------------------------------------------------- */

/* Drive configurations exercised by the drive and cell families (all valid). */
static const mc_drive_config_t drive_cfgs[] = {
    /* supply, vmax, kt, kv, pwm_top, rate, window */
    {9000, MC_VMAX_ABS_MV, 7500, 49800, 2400, 2000, -1},   /* rig default, 20 kHz */
    {9000, MC_VMAX_ABS_MV, 7500, 49800, 255, 2000, 2},     /* 8-bit PWM */
    {9000, 3000, 7500, 47900, 4095, 20000, 5},             /* 12-bit, fast tick */
    {12000, MC_VMAX_ABS_MV, 7500, 49800, 1023, 500, 8},    /* long window */
    {5000, 5000, 7500, 49800, 4095, 50000, 6},             /* low supply */
    {24000, MC_VMAX_ABS_MV, 10000, 10000, 511, 1000, 1},   /* high supply, slow motor */
};
#define N_CFGS ((int32_t)(sizeof(drive_cfgs) / sizeof(drive_cfgs[0])))

static void random_raw(rng_t *g, int32_t v[5])
{
    int32_t g1 = (rnd(g) & 7u) == 0 ? MC_GAIN_MAX : r_range(g, 1, MC_GAIN_MAX);
    v[0] = r_range(g, -MC_GAIN_MAX, MC_GAIN_MAX);
    v[1] = r_range(g, -MC_GAIN_MAX, MC_GAIN_MAX);
    v[2] = g1;
    v[3] = (rnd(g) & 7u) == 0 ? -MC_GAIN_MAX : r_range(g, -MC_GAIN_MAX, g1 - 1);
    v[4] = r_range(g, 0, MC_COUNTS_PER_REV * 16);
}

static void fam_reaction(const mcv_api_t *api, rng_t *g, mcv_sink_t *s)
{
    uint32_t rec[MCV_WORDS];
    mc_reaction_phys_t dp;
    mc_reaction_t law;
    FN(api, mc_cell_default_params, f_c_defp)(&dp);
    for (uint32_t i = 0; i < MCV_N_REACTION; i++) {
        int32_t v[5];
        int rc;
        uint32_t sub = rnd(g) & 3u;
        if (sub == 0) {
            rc = FN(api, mc_reaction_from_phys, f_from_phys)(&law, &dp);
        } else {
            random_raw(g, v);
            rc = FN(api, mc_reaction_set_raw, f_set_raw)(&law, v[0], v[1], v[2], v[3], v[4]);
        }
        int32_t a = r_wide(g, 2100), b = r_wide(g, 2100), ra = 0, rb = 0;
        FN(api, mc_reaction_eval, f_eval)(&law, a, b, &ra, &rb);
        rec_clear(rec, MCV_FAM_REACTION, sub, i);
        rec[1] = W(a); rec[2] = W(b); rec[3] = W(law.g_ab); rec[4] = W(law.g_sigma);
        rec[5] = W(law.g1); rec[6] = W(law.g2); rec[7] = W(law.astar_q4);
        rec[8] = W(ra); rec[9] = W(rb);
        rec[10] = W(FN(api, mc_psi_prime, f_psi)(&law, a));
        rec[11] = W(FN(api, mc_psi_prime, f_psi)(&law, b));
        rec[12] = W(rc); rec[13] = W(law.c1);
        emit(s, rec);
    }
}

static mc_cell_t cell; /* ~2.3 KB: static, the target stack is small */

static void random_phys(rng_t *g, mc_reaction_phys_t *p, int valid)
{
    if (valid) {
        p->k_ab_unm = r_range(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->sigma_unm = r_range(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->k1_unm = r_range(g, 1, MC_K_MAX_UNM);
        p->k2_unm = r_range(g, -MC_K_MAX_UNM, p->k1_unm - 1);
        p->astar_urad = r_range(g, 0, MC_ASTAR_MAX_URAD);
    } else {
        p->k_ab_unm = r_field(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->sigma_unm = r_field(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->k1_unm = r_field(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->k2_unm = r_field(g, -MC_K_MAX_UNM, MC_K_MAX_UNM);
        p->astar_urad = r_field(g, 0, MC_ASTAR_MAX_URAD);
    }
}

static void random_drive_cfg(rng_t *g, mc_drive_config_t *c, int valid)
{
    if (valid) {
        c->supply_mv = r_range(g, 4500, 37000);
        c->vmax_mv = r_range(g, 1, MC_VMAX_ABS_MV < c->supply_mv ? MC_VMAX_ABS_MV : c->supply_mv);
        c->kt_unm_per_v = r_range(g, 1000, 100000);
        c->kv_mrad_per_vs = r_range(g, 1000, 1000000);
        c->pwm_top = r_range(g, 255, 4095);
        c->ctrl_rate_hz = r_range(g, 100, 50000);
        c->vel_window_log2 = r_range(g, -1, 8);
    } else {
        c->supply_mv = r_field(g, 4500, 37000);
        c->vmax_mv = r_field(g, 1, MC_VMAX_ABS_MV);
        c->kt_unm_per_v = r_field(g, 1000, 100000);
        c->kv_mrad_per_vs = r_field(g, 1000, 1000000);
        c->pwm_top = r_field(g, 255, 4095);
        c->ctrl_rate_hz = r_field(g, 100, 50000);
        c->vel_window_log2 = r_field(g, -1, 8);
    }
}

static void put_law(uint32_t *o, const mc_reaction_t *r)
{
    o[0] = W(r->g_ab); o[1] = W(r->g_sigma); o[2] = W(r->g1); o[3] = W(r->g2);
    o[4] = W(r->astar_q4); o[5] = W(r->c1);
}

static void fam_params(const mcv_api_t *api, rng_t *g, mcv_sink_t *s)
{
    uint32_t rec[MCV_WORDS];
    mc_reaction_t law, before;
    mc_drive_t drv, dbefore;
    mc_drive_config_t cfg;
    mc_reaction_phys_t p;
    FN(api, mc_cell_init, f_c_init)(&cell);
    FN(api, mc_reaction_set_raw, f_set_raw)(&law, 1000, 2000, 30000, -30000, 600);
    FN(api, mc_drive_configure, f_drv_conf)(&drv, &drive_cfgs[0]);
    for (uint32_t i = 0; i < MCV_N_PARAMS; i++) {
        uint32_t sub = i % 6u;
        int valid = (rnd(g) & 1u) != 0;
        int rc = 0, same = 0;
        rec_clear(rec, MCV_FAM_PARAMS, sub, i);
        switch (sub) {
        case 0: { /* raw reaction set */
            int32_t v[5];
            if (valid) {
                random_raw(g, v);
            } else {
                v[0] = r_field(g, -MC_GAIN_MAX, MC_GAIN_MAX);
                v[1] = r_field(g, -MC_GAIN_MAX, MC_GAIN_MAX);
                v[2] = r_field(g, -MC_GAIN_MAX, MC_GAIN_MAX);
                v[3] = r_field(g, -MC_GAIN_MAX, MC_GAIN_MAX);
                v[4] = r_field(g, 0, MC_COUNTS_PER_REV * 16);
            }
            bytes_copy(&before, &law, sizeof law);
            rc = FN(api, mc_reaction_set_raw, f_set_raw)(&law, v[0], v[1], v[2], v[3], v[4]);
            same = bytes_equal(&before, &law, sizeof law);
            for (int k = 0; k < 5; k++)
                rec[1 + k] = W(v[k]);
            put_law(&rec[10], &law);
            break;
        }
        case 1: /* physical reaction set */
        case 2: /* the same through the cell (running parameters) */
            random_phys(g, &p, valid);
            rec[1] = W(p.k_ab_unm); rec[2] = W(p.sigma_unm); rec[3] = W(p.k1_unm);
            rec[4] = W(p.k2_unm); rec[5] = W(p.astar_urad);
            if (sub == 1) {
                bytes_copy(&before, &law, sizeof law);
                rc = FN(api, mc_reaction_from_phys, f_from_phys)(&law, &p);
                same = bytes_equal(&before, &law, sizeof law);
                put_law(&rec[10], &law);
            } else {
                bytes_copy(&before, &cell.law, sizeof before);
                rc = FN(api, mc_cell_set_params, f_c_setp)(&cell, &p);
                same = bytes_equal(&before, &cell.law, sizeof before);
                put_law(&rec[10], &cell.law);
            }
            break;
        case 3: /* drive configuration */
            random_drive_cfg(g, &cfg, valid);
            rec[1] = W(cfg.supply_mv); rec[2] = W(cfg.vmax_mv); rec[3] = W(cfg.kt_unm_per_v);
            rec[4] = W(cfg.kv_mrad_per_vs); rec[5] = W(cfg.pwm_top);
            rec[6] = W(cfg.ctrl_rate_hz); rec[7] = W(cfg.vel_window_log2);
            bytes_copy(&dbefore, &drv, sizeof drv);
            rc = FN(api, mc_drive_configure, f_drv_conf)(&drv, &cfg);
            same = bytes_equal(&dbefore, &drv, sizeof drv);
            rec[10] = W(drv.m_t); rec[11] = W(drv.m_b); rec[12] = W((drv.s_t << 8) | drv.s_b);
            rec[13] = W(drv.duty_max); rec[14] = W((drv.pwm_top << 8) | drv.vel_log2);
            rec[15] = W(drv.duty_limit);
            break;
        case 4: { /* runaway limit and user duty limit */
            int32_t n = r_field(g, 1, MC_ANGLE_CLAMP);
            int32_t before_n = cell.runaway_counts;
            rc = FN(api, mc_cell_set_runaway, f_c_runaway)(&cell, n);
            same = before_n == cell.runaway_counts;
            int32_t lim = r_wide(g, 5000);
            int32_t got = FN(api, mc_drive_set_limit, f_drv_limit)(&drv, lim);
            rec[1] = W(n); rec[2] = W(lim);
            rec[10] = W(cell.runaway_counts); rec[11] = W(got); rec[12] = W(drv.duty_limit);
            break;
        }
        default: { /* perturbation command */
            int chain = r_range(g, -1, 2);
            int32_t t = r_field(g, -MC_PERTURB_MAX_UNM, MC_PERTURB_MAX_UNM);
            uint32_t ticks = rnd(g);
            uint32_t bt = cell.pert_ticks;
            int32_t bq = cell.pert_torque;
            rc = FN(api, mc_cell_perturb, f_c_perturb)(&cell, chain, t, ticks);
            same = bt == cell.pert_ticks && bq == cell.pert_torque;
            rec[1] = W(chain); rec[2] = W(t); rec[3] = ticks;
            rec[10] = W(cell.pert_torque); rec[11] = cell.pert_ticks; rec[12] = cell.pert_chain;
            break;
        }
        }
        rec[8] = W(rc);
        rec[9] = W(same);
        emit(s, rec);
    }
}

static void fam_drive(const mcv_api_t *api, rng_t *g, mcv_sink_t *s)
{
    uint32_t rec[MCV_WORDS];
    mc_drive_t drv[N_CFGS];
    int rcs[N_CFGS];
    for (int32_t k = 0; k < N_CFGS; k++) {
        static const mc_drive_t zero; /* defined contents even if rejected */
        drv[k] = zero;
        rcs[k] = FN(api, mc_drive_configure, f_drv_conf)(&drv[k], &drive_cfgs[k]);
    }
    for (uint32_t i = 0; i < MCV_N_DRIVE; i++) {
        int32_t k = r_range(g, 0, N_CFGS - 1);
        mc_drive_t d = drv[k];
        int32_t lim = -1;
        if ((rnd(g) & 7u) == 0)
            lim = FN(api, mc_drive_set_limit, f_drv_limit)(&d, r_wide(g, 4200));
        int32_t tau = r_wide(g, 1 << 22);
        int32_t dth = r_wide(g, 1100);
        int bemf = (int)(rnd(g) & 1u);
        mc_drive_out_t out = {0, 0, 0};
        FN(api, mc_drive_command, f_drv_cmd)(&d, tau, dth, bemf, &out);
        int32_t q = out.dir ? (int32_t)out.duty : -(int32_t)out.duty;   /* signed duty */
        rec_clear(rec, MCV_FAM_DRIVE, (uint32_t)k, i);
        rec[1] = W(tau); rec[2] = W(dth); rec[3] = W(bemf); rec[4] = W(lim);
        rec[5] = W(rcs[k]);
        rec[8] = W(q); rec[9] = out.duty; rec[10] = out.dir; rec[11] = out.enable;
        rec[12] = W(d.duty_limit); rec[13] = W(d.duty_max);
        emit(s, rec);
    }
}

static const uint8_t gray_next[4] = {1, 3, 0, 2}; /* 00->01->11->10->00 */
static const uint8_t gray_prev[4] = {2, 0, 3, 1};

static void fam_quad(const mcv_api_t *api, rng_t *g, mcv_sink_t *s)
{
    uint32_t rec[MCV_WORDS];
    mc_quad_t q;
    mc_quad_snap_t snap;
    for (uint32_t i = 0; i < MCV_N_QUAD; i++) {
        uint8_t ab = (uint8_t)(rnd(g) & 3u);
        int32_t start;
        uint32_t pick = rnd(g) & 7u;
        if (pick == 0)
            start = INT32_MAX - r_range(g, 0, 12);
        else if (pick == 1)
            start = INT32_MIN + r_range(g, 0, 12);
        else
            start = r_wide(g, 3000);
        int up = (int)(rnd(g) & 1u);
        FN(api, mc_quad_init, f_q_init)(&q, ab);
        FN(api, mc_quad_set_pos, f_q_setpos)(&q, start);
        uint32_t seq = 0;
        for (int e = 0; e < 16; e++) {
            uint8_t nab;
            uint32_t r = rnd(g) & 15u;
            if (r < 8)
                nab = up ? gray_next[ab] : gray_prev[ab];
            else if (r < 11)
                nab = up ? gray_prev[ab] : gray_next[ab];
            else if (r < 13)
                nab = ab;                       /* no change (spurious interrupt) */
            else if (r < 15)
                nab = (uint8_t)(ab ^ 3u);       /* glitch: both channels changed */
            else
                nab = (uint8_t)(rnd(g) & 0xffu); /* garbage high bits must be masked */
            seq |= (uint32_t)(nab & 3u) << (2 * e);
            FN(api, mc_quad_update, f_q_update)(&q, nab);
            ab = (uint8_t)(nab & 3u);
        }
        FN(api, mc_quad_snapshot, f_q_snap)(&q, &snap);
        rec_clear(rec, MCV_FAM_QUAD, (uint32_t)up, i);
        rec[1] = W(start); rec[2] = seq;
        rec[8] = W(q.pos); rec[9] = q.errors; rec[10] = q.ab; rec[11] = q.saturated;
        rec[12] = W(snap.pos); rec[13] = snap.errors; rec[14] = snap.saturated;
        emit(s, rec);
    }
}

static uint32_t pack_out(const mc_drive_out_t *o)
{
    return (uint32_t)o->duty | ((uint32_t)o->dir << 16) | ((uint32_t)o->enable << 24);
}

static void fam_cell(const mcv_api_t *api, rng_t *g, mcv_sink_t *s)
{
    uint32_t rec[MCV_WORDS];
    mc_reaction_phys_t p;
    mc_drive_config_t cfg;
    uint32_t idx = 0;
    for (uint32_t sq = 0; sq < MCV_CELL_SEQS; sq++) {
        FN(api, mc_cell_init, f_c_init)(&cell);
        if (rnd(g) & 1u) {
            random_phys(g, &p, (int)(rnd(g) & 3u));
            FN(api, mc_cell_set_params, f_c_setp)(&cell, &p);
        }
        FN(api, mc_cell_set_drive, f_c_setd)(&cell, &drive_cfgs[r_range(g, 0, N_CFGS - 1)]);
        if (rnd(g) & 1u) /* else the default, 800 counts */
            FN(api, mc_cell_set_runaway, f_c_runaway)(&cell, (rnd(g) & 3u)
                                                                  ? r_range(g, 400, MC_ANGLE_CLAMP)
                                                                  : r_field(g, 1, MC_ANGLE_CLAMP));
        FN(api, mc_cell_enable, f_c_flag)(&cell, (rnd(g) & 3u) != 0);
        FN(api, mc_cell_set_bemf, f_c_flag)(&cell, (int)(rnd(g) & 1u));
        int32_t pa = (rnd(g) & 3u) ? r_range(g, -50, 50) : r_wide(g, 3000);
        int32_t pb = (rnd(g) & 3u) ? r_range(g, -50, 50) : r_wide(g, 3000);
        uint32_t ea = (rnd(g) & 3u) ? 0u : rnd(g), eb = (rnd(g) & 3u) ? 0u : rnd(g);
        FN(api, mc_cell_zero, f_c_zero)(&cell, pa, pb);
        int32_t va = r_range(g, -6, 6), vb = r_range(g, -6, 6);
        for (uint32_t t = 0; t < MCV_CELL_TICKS; t++, idx++) {
            uint32_t action = rnd(g) & 31u;
            int32_t arg = 0;
            int rc = 0;
            if (t == 0 && (rnd(g) & 1u))
                action = 0;
            switch (action) {
            case 0: { /* one PRNG call per statement: argument order is unspecified */
                int chain = r_range(g, 0, 2);
                uint32_t n = (uint32_t)r_range(g, 0, 60);
                arg = r_field(g, -MC_PERTURB_MAX_UNM, MC_PERTURB_MAX_UNM);
                rc = FN(api, mc_cell_perturb, f_c_perturb)(&cell, chain, arg, n);
                break;
            }
            case 1:
                FN(api, mc_cell_zero, f_c_zero)(&cell, pa, pb);
                break;
            case 2:
                FN(api, mc_cell_clear_faults, f_c_void)(&cell);
                break;
            case 3:
                if (rnd(g) & 1u)
                    FN(api, mc_cell_report_driver_fault, f_c_void)(&cell);
                break;
            case 4:
                FN(api, mc_cell_enable, f_c_flag)(&cell, !cell.enabled);
                break;
            case 5:
                FN(api, mc_cell_set_bemf, f_c_flag)(&cell, !cell.bemf_comp);
                break;
            case 6:
                random_phys(g, &p, (int)(rnd(g) & 1u));
                rc = FN(api, mc_cell_set_params, f_c_setp)(&cell, &p);
                break;
            case 7:
                arg = r_field(g, 1, MC_ANGLE_CLAMP);
                rc = FN(api, mc_cell_set_runaway, f_c_runaway)(&cell, arg);
                break;
            case 8:
                if (rnd(g) & 1u) {
                    random_drive_cfg(g, &cfg, (int)(rnd(g) & 1u));
                    rc = FN(api, mc_cell_set_drive, f_c_setd)(&cell, &cfg);
                } else {
                    arg = r_range(g, 0, N_CFGS - 1);
                    rc = FN(api, mc_cell_set_drive, f_c_setd)(&cell, &drive_cfgs[arg]);
                }
                break;
            default:
                break;
            }
            /* plant stand-in: a random walk with occasional jumps and error bursts */
            if ((rnd(g) & 15u) == 0)
                va = r_range(g, -6, 6);
            if ((rnd(g) & 15u) == 0)
                vb = r_range(g, -6, 6);
            pa = sat_add(pa, va + r_range(g, -1, 1));
            pb = sat_add(pb, vb + r_range(g, -1, 1));
            if ((rnd(g) & 127u) == 0)
                pa = sat_add(pa, r_wide(g, 3000));
            if ((rnd(g) & 127u) == 0)
                pb = sat_add(pb, r_wide(g, 3000));
            if ((rnd(g) & 63u) == 0)
                ea += (uint32_t)r_range(g, 1, 3);
            if ((rnd(g) & 63u) == 0)
                eb += (uint32_t)r_range(g, 1, 3);
            if ((rnd(g) & 255u) == 0)
                ea += (uint32_t)r_range(g, 0, 400);
            uint8_t sat = (uint8_t)((rnd(g) & 255u) == 0 ? 1u + (rnd(g) & 1u) : 0u);
            mc_quad_snap_t sa = {pa, ea, (uint8_t)(sat & 1u)};
            mc_quad_snap_t sb = {pb, eb, (uint8_t)(sat >> 1)};
            uint16_t f = FN(api, mc_cell_tick, f_c_tick)(&cell, &sa, &sb);
            rec_clear(rec, MCV_FAM_CELL, action, idx);
            rec[1] = W(pa); rec[2] = W(pb); rec[3] = ea; rec[4] = eb; rec[5] = sat;
            rec[6] = W(rc); rec[7] = W(arg);
            rec[8] = f; rec[9] = pack_out(&cell.out[0]); rec[10] = pack_out(&cell.out[1]);
            rec[11] = W(cell.torque[0]); rec[12] = W(cell.torque[1]);
            rec[13] = W(cell.theta[0]); rec[14] = W(cell.theta[1]);
            rec[15] = cell.pert_ticks ^ ((uint32_t)cell.faults << 16);
            emit(s, rec);
        }
    }
}

uint32_t mcv_run(const mcv_api_t *api, uint32_t seed, mcv_sink_t *sink)
{
    rng_t g;
    g.s = seed ? seed : 0x9e3779b9u; /* xorshift must not start at 0 */
    fam_reaction(api, &g, sink);
    fam_params(api, &g, sink);
    fam_drive(api, &g, sink);
    fam_quad(api, &g, sink);
    fam_cell(api, &g, sink);
    if (sink->flush)
        sink->flush(sink);
    return sink->n_records;
}
