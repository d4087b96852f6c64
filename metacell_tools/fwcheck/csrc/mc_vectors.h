/* Golden-vector generator shared by the host (cffi), QEMU and Unity harnesses. */
#ifndef MC_VECTORS_H
#define MC_VECTORS_H

#include <stdint.h>

/*
 * One deterministic program (xorshift32 seeded by the caller) drives the cell
 * library through every entry point and emits fixed-size records:
 *
 *   w[0]      tag = family << 24 | sub << 16 | index-in-family & 0xffff
 *   w[1..7]   inputs (int32 as two's complement words)
 *   w[8..15]  outputs
 *
 * The library is reached only through a table of entry points (mcv_api_t), so
 * the host can hand in the addresses of the functions of the cffi build
 * (host_emulator.firmware.load()) and the target links them directly: both
 * sides run this same file against their own build of lib/metacell.
 * No float, no division, no undefined behaviour (all mixing is unsigned).
 */
#define MCV_WORDS 16
#define MCV_IN 1
#define MCV_OUT 8

enum {
    MCV_FAM_REACTION = 1,  /* mc_reaction_set_raw + mc_reaction_eval + mc_psi_prime */
    MCV_FAM_PARAMS = 2,    /* validation codes, rejected sets leave old values */
    MCV_FAM_DRIVE = 3,     /* mc_drive_command over several configs */
    MCV_FAM_QUAD = 4,      /* mc_quad_update edge streams with glitches */
    MCV_FAM_CELL = 5,      /* multi-tick mc_cell_tick sequences */
};

/* Records per family (fixed, independent of the seed). */
#define MCV_N_REACTION 40000
#define MCV_N_PARAMS 6000
#define MCV_N_DRIVE 30000
#define MCV_N_QUAD 10000
#define MCV_CELL_SEQS 200
#define MCV_CELL_TICKS 100
#define MCV_N_CELL 20000   /* MCV_CELL_SEQS * MCV_CELL_TICKS */
#define MCV_N_TOTAL 106000

/* Entry points of the library, in table order (names are the C symbols). */
#define MCV_API(X)                                                         \
    X(mc_reaction_set_raw) X(mc_reaction_from_phys) X(mc_reaction_eval)    \
    X(mc_psi_prime) X(mc_drive_default_config) X(mc_drive_configure)       \
    X(mc_drive_set_limit) X(mc_drive_command)                              \
    X(mc_quad_init) X(mc_quad_update) X(mc_quad_snapshot)                  \
    X(mc_quad_set_pos) X(mc_cell_default_params) X(mc_cell_init)           \
    X(mc_cell_set_params) X(mc_cell_set_drive) X(mc_cell_set_runaway)      \
    X(mc_cell_enable) X(mc_cell_set_bemf) X(mc_cell_perturb)               \
    X(mc_cell_zero) X(mc_cell_clear_faults) X(mc_cell_report_driver_fault) \
    X(mc_cell_tick)

#define MCV_ENUM_ENTRY(name) MCV_FN_##name,
enum { MCV_API(MCV_ENUM_ENTRY) MCV_N_FN };

typedef void (*mcv_fn)(void);
/* Direct table for a build linked with the library (target, Unity):
 *   static const mcv_api_t api = MCV_API_DIRECT;   (needs mc_cell.h) */
#define MCV_ADDR(name) (mcv_fn) name,
#define MCV_API_DIRECT {{MCV_API(MCV_ADDR)}}
typedef struct {
    mcv_fn fn[MCV_N_FN];
} mcv_api_t;

/* Record sink: records go to data[0..cap_words); when full, flush() (if any)
 * empties it. fnv is FNV-1a (32 bit) over all words, n_records the count. */
typedef struct mcv_sink {
    uint32_t *data;
    uint32_t cap_words;
    uint32_t n_words;
    uint32_t n_records;
    uint32_t fnv;
    uint32_t overflow;   /* set when the buffer filled and there was no flush */
    void (*flush)(struct mcv_sink *s);
    uint32_t fam_fnv[8];   /* FNV-1a per family (index = family) */
    uint32_t fam_count[8]; /* records per family */
} mcv_sink_t;

void mcv_sink_init(mcv_sink_t *s, uint32_t *data, uint32_t cap_words);
/* Run every family; returns the number of records emitted (MCV_N_TOTAL). */
uint32_t mcv_run(const mcv_api_t *api, uint32_t seed, mcv_sink_t *sink);
/* The shared PRNG, exposed for tests: x ^= x<<13; x ^= x>>17; x ^= x<<5. */
uint32_t mcv_xorshift32(uint32_t *state);

#endif /* MC_VECTORS_H */
