/* Non-reciprocal reaction torques R_a, R_b with the tri-linear psi' (docs/physics.md#reaction-torques). */
#ifndef MC_REACTION_H
#define MC_REACTION_H

#include <stdint.h>
#include "../mc_fixed.h"

/*
 * Continuous law (docs/physics.md#reaction-torques), angles in rad, torques in N*m:
 *   R_a = k_ab*(beta - alpha) - psi'(alpha) - sigma*beta
 *   R_b = k_ab*(alpha - beta)
 *   psi'(alpha) = k1*(alpha + a_s)  alpha < -b;  k2*alpha  |alpha| <= b;
 *                 k1*(alpha - a_s)  alpha >  b;  b = k1*a_s/(k1 - k2)
 *
 * Because psi' is continuous and k1 > k2, the breakpoint needs no division:
 *   psi'(x) = sign(x) * max(k2*|x|, k1*|x| - c1),   c1 = k1*a_s
 *
 * Discrete form implemented (all int32, TU = 2^-5 uN*m, angles in counts):
 *   x_a = clamp(alpha, +-MC_ANGLE_CLAMP), x_b = clamp(beta, +-MC_ANGLE_CLAMP)
 *   R_a = g_ab*(x_b - x_a) - psi(x_a) - g_sigma*x_b
 *   R_b = g_ab*(x_a - x_b)
 * With |g| <= 2^17 and |x| <= 2^11 every product is < 2^29 and the sum < 2^31:
 * no intermediate can overflow.
 */
typedef struct {
    int32_t g_ab;     /* TU/count */
    int32_t g_sigma;  /* TU/count */
    int32_t g1;       /* TU/count, k1 */
    int32_t g2;       /* TU/count, k2 */
    int32_t astar_q4; /* Q4 counts */
    int32_t c1;       /* TU = (g1*astar_q4) >> 4, derived */
} mc_reaction_t;

/* Physical parameter set, integer SI-derived units (the on-wire form). */
typedef struct {
    int32_t k_ab_unm;      /* uN*m/rad */
    int32_t sigma_unm;     /* uN*m/rad */
    int32_t k1_unm;        /* uN*m/rad */
    int32_t k2_unm;        /* uN*m/rad */
    int32_t astar_urad;    /* urad */
} mc_reaction_phys_t;

/* Accepted ranges (checked by mc_reaction_from_phys): MC_K_MAX_UNM (|k| for every gain, uN*m/rad) and
 * MC_ASTAR_MAX_URAD (0 <= a_s), generated into mc_units.h from protocol/definition.py. */

enum {
    MC_OK = 0,
    MC_ERR_RANGE = -1,     /* a value outside its documented range */
    MC_ERR_SHAPE = -2,     /* k1 <= k2 or k1 <= 0: psi' would not be bistable/continuous */
    MC_ERR_CONFIG = -3,    /* drive configuration out of range */
    MC_ERR_ARG = -4,       /* bad argument (index, null) */
};

/* Validate and convert; on any error *out is left untouched. */
int mc_reaction_from_phys(mc_reaction_t *out, const mc_reaction_phys_t *p);
/* Validate a raw (fixed-point) set and derive c1; on error *out is untouched. */
int mc_reaction_set_raw(mc_reaction_t *out, int32_t g_ab, int32_t g_sigma,
                        int32_t g1, int32_t g2, int32_t astar_q4);

int32_t mc_psi_prime(const mc_reaction_t *r, int32_t x);
void mc_reaction_eval(const mc_reaction_t *r, int32_t alpha, int32_t beta,
                      int32_t *ra, int32_t *rb);

#ifndef MC_CDEF
/* psi'(x) for |x| <= MC_ANGLE_CLAMP:  sign(x) * max(k2|x|, k1|x| - c1) */
MC_INLINE int32_t mc_psi_prime_inl(const mc_reaction_t *r, int32_t x)
{
    int32_t ax = x < 0 ? -x : x;
    int32_t inner = r->g2 * ax;
    int32_t outer = r->g1 * ax - r->c1;
    int32_t p = inner > outer ? inner : outer;
    return x < 0 ? -p : p;
}

/* The law for |xa|, |xb| <= MC_ANGLE_CLAMP (the tick's angles are clamped once):
 *   R_a = g_ab*(x_b - x_a) - psi'(x_a) - g_sigma*x_b,   R_b = -g_ab*(x_b - x_a) */
MC_INLINE void mc_reaction_eval_inl(const mc_reaction_t *r, int32_t xa, int32_t xb,
                                    int32_t *ra, int32_t *rb)
{
    int32_t coupling = r->g_ab * (xb - xa);
    *ra = coupling - mc_psi_prime_inl(r, xa) - r->g_sigma * xb;
    *rb = -coupling;
}
#endif

#endif /* MC_REACTION_H */
