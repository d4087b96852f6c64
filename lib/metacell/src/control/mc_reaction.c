/* Reaction law in fixed point; the equations are written out in mc_reaction.h. */
#include "mc_reaction.h"

int32_t mc_psi_prime(const mc_reaction_t *r, int32_t x)
{
    return mc_psi_prime_inl(r, mc_clamp_sym(x, MC_ANGLE_CLAMP));
}

void mc_reaction_eval(const mc_reaction_t *r, int32_t alpha, int32_t beta,
                      int32_t *ra, int32_t *rb)
{
    mc_reaction_eval_inl(r, mc_clamp_sym(alpha, MC_ANGLE_CLAMP),
                         mc_clamp_sym(beta, MC_ANGLE_CLAMP), ra, rb);
}
