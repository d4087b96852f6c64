/* Linearly implicit (Rosenbrock-W) IMEX Euler plant stepper (HE_STEP_IMEX): bands + damping implicit, reaction explicit. */
#ifndef HE_IMEX_H
#define HE_IMEX_H

#include "he_step.h"

/*
 * HE_STEP_IMEX: linearly implicit (Rosenbrock-W) Euler, order 1. The band torques (their tangent
 *   stiffness, a tridiagonal matrix per chain) and the viscous/back-EMF damping are implicit; the
 *   reaction torque, motor voltage and perturbations are explicit:
 *     Kb = -dF_band/dx at x0 (bond slope s_j = tangent stiffness of bond j,j+1; small-angle slope
 *          for the geometric beta form: a W-method, still order 1)
 *     inertia:     (I + h C + h^2 Kb) v1 = I v0 + h F(t, x0),   x1 = x0 + h v1
 *     overdamped:  (C + h Kb) (x1 - x0) = h F(t, x0),           v1 = (x1 - x0)/h
 *   one Thomas solve per chain per step. For the linear lattice without reaction this is backward
 *   Euler (unconditionally stable); the limit comes from the explicit reaction only:
 *     inertia: h < (c + sqrt(c^2 + 4 wr2)) / wr2,  c = C_min/I, wr2 = k_react/I
 *     overdamped: h < 2 C_min / k_react
 *   k_react = Gershgorin bound of the reaction Jacobian (he_react_stiffness in he_plant.c); INFINITY without
 *   reaction (hil: the firmware's torque is held per tick).
 */
/*
 * Topologies (he_plant_t.bonds): the open chain's W is tridiagonal per chain (Thomas, above). On an edge list
 * (ring, sheet) W = D + w K per chain, K the bond Laplacian with the tangent slopes (symmetric; positive definite
 * while every slope is >= 0, the taut or slack cubic band's and the linear band's), solved by conjugate
 * gradients with W's diagonal as preconditioner, from the Jacobi guess, to the relative residual
 * |r - W u|_2 <= HE_IMEX_CG_RTOL |r|_2 in at most HE_IMEX_CG_MAXIT(n) iterations; HE_ERR_SOLVE when it does not
 * get there (or meets a non-positive curvature). W = I + h C + h^2 K is close to its diagonal for the steps
 * the run takes, so it converges in a few iterations.
 */
#define HE_IMEX_CG_RTOL 1e-13
#define HE_IMEX_CG_MAXIT(n) (2 * (n) + 100)

/* Entry points: he_imex_advance, he_imex_limit (declared in he_step.h). */

#endif /* HE_IMEX_H */
