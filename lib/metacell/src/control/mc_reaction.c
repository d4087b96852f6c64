/* Reaction law in fixed point; the equations are written out in mc_reaction.h. */
#include "mc_reaction.h"
#include "../mc_fixed.h"

int32_t mc_psi_prime(const mc_reaction_t *r, int32_t x)
{
    x = mc_clamp_i32(x, -MC_ANGLE_CLAMP, MC_ANGLE_CLAMP);
    int32_t ax = mc_abs_i32(x);
    /* psi'(|x|) = max(k2*|x|, k1*|x| - c1) */
    int32_t inner = r->g2 * ax;
    int32_t outer = r->g1 * ax - r->c1;
    int32_t p = inner > outer ? inner : outer;
    return x < 0 ? -p : p;
}

void mc_reaction_eval(const mc_reaction_t *r, int32_t alpha, int32_t beta,
                      int32_t *ra, int32_t *rb)
{
    int32_t xa = mc_clamp_i32(alpha, -MC_ANGLE_CLAMP, MC_ANGLE_CLAMP);
    int32_t xb = mc_clamp_i32(beta, -MC_ANGLE_CLAMP, MC_ANGLE_CLAMP);
    /* coupling = k_ab*(beta - alpha) */
    int32_t coupling = r->g_ab * (xb - xa);
    *ra = coupling - mc_psi_prime(r, xa) - r->g_sigma * xb;
    *rb = -coupling;
}
