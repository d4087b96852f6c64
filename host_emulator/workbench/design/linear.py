"""Step 1, the first guess: the chain's linear theory (analysis.chain) scored against the target and maximised by
differential evolution."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ...analysis.chain import chain_modes
from ...analysis.stability import theory_of
from ...params import Params
from .constants import DOMAIN_FILL_MODE, MIN_GROWTH_PER_S
from .landing import final_walls, interior_cells
from .space import Space, _shape_ok
from .target import Target


def linear_score(p: Params, target: Target) -> tuple[float, dict]:
    """(score, facts) of the chain's linear theory for the target: > 1 when the fastest mode is stationary, grows
    at least MIN_GROWTH_PER_S and has the target's walls (rest cells under a fifth of its peak); then 1 + gap,
    gap = (g1 - max(g2, 0)) / g1 in [0, 1]. Below 1: how far it is (walls off, growth, kind)."""
    if not _shape_ok(p):
        return -3.0, {"why": "k1 <= max(k2, 0)"}
    res = chain_modes(p, theory_of("hil", p), count=2)
    top = res["modes"][0]
    g1 = top["growth_per_s"]
    g2 = res["modes"][1]["growth_per_s"] if len(res["modes"]) > 1 else -math.inf
    alpha = top["alpha"]
    walls = final_walls(alpha, target.rest, 0.1 * np.abs(alpha).max())
    facts = {
        "growth_per_s": g1,
        "next_growth_per_s": g2,
        "kind": top["kind"],
        "walls": walls,
        "mode_alpha": [float(v) for v in alpha],
    }
    if top["kind"] != "stationary":
        return -2.0 + 0.1 * math.tanh(-g1 / 50), facts
    if g1 < MIN_GROWTH_PER_S:
        return -1.0 + 0.5 * math.tanh(g1 / 20), facts
    miss: float
    if target.kind == "lambda":
        miss = abs(len(walls) - target.z)
    else:
        miss = len(set(walls) ^ set(target.walls)) + sum(
            min(abs(w - t) for w in walls) if walls else 1.0 for t in target.walls
        ) * (set(walls) != set(target.walls))
    if target.rest:
        r = np.abs(alpha[[c - 1 for c in target.rest]]).max() / np.abs(alpha).max()
        miss += max(0.0, r - 0.2) * 5
    if not miss:  # every cell off the walls carries a share of the mode's peak (no part of a domain near rest)
        inner = [j - 1 for j in interior_cells(alpha.size, walls, target.rest)]
        if inner:
            fill = float(np.abs(alpha[inner]).min() / np.abs(alpha).max())
            miss += max(0.0, DOMAIN_FILL_MODE - fill) * 4
    if miss:
        return 0.5 - 0.1 * miss, facts
    gap = (g1 - max(g2, 0.0)) / g1
    return 1.0 + gap, facts


def first_guess(space: Space, target: Target, seed: int = 1, maxiter: int = 60) -> tuple[np.ndarray, float, dict]:
    """Differential evolution on the linear score (scipy.optimize), from the base scene's values too."""
    return evolve_score(space, lambda p: linear_score(p, target), seed, maxiter)


def evolve_score(
    space: Space, score: Callable[[Params], tuple[float, dict]], seed: int, maxiter: int
) -> tuple[np.ndarray, float, dict]:
    """(x, score, facts): differential evolution (scipy.optimize) maximising score(space.params(x))[0] from a random
    population that holds the base scene's values too; the first guess of a chain (linear_score) and of a sheet
    (sheet_linear.sheet_linear_score)."""
    from scipy.optimize import differential_evolution

    def f(x):
        return -score(space.params(x))[0]

    rng = np.random.default_rng(seed)
    lo = np.array([b[0] for b in space.bounds])
    hi = np.array([b[1] for b in space.bounds])
    npop = max(15, 8 * len(lo))
    init = lo + (hi - lo) * rng.random((npop, len(lo)))
    init[0] = space.x0()
    r = differential_evolution(
        f, space.bounds, init=init, seed=seed, maxiter=maxiter, tol=1e-6, polish=False, updating="immediate"
    )
    x = np.asarray(r.x)
    best, facts = score(space.params(x))
    return x, best, facts
