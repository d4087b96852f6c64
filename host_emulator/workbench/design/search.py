"""Step 2, the search: differential evolution over batched hil ensembles, seeded around the first guess."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .constants import CHECK_SEED0, CLOSE_WEIGHT, FULL_BONUS, MARGIN_WEIGHT, NOMINAL_PUSH, SEARCH_PUSHES, SEARCH_SEED0
from .ensembles import Runner, _noise, _scene_table
from .landing import _landed, closeness
from .linear import linear_score
from .space import Space, _shape_ok
from .target import Push, Target


def _search_tables(base_table, p, pushes, seeds: int) -> list[dict]:
    t = [_noise(_scene_table(base_table, p, pushes, *NOMINAL_PUSH), SEARCH_SEED0 + s) for s in range(seeds)]
    t += [_noise(_scene_table(base_table, p, pushes, tq, du), None) for tq, du in SEARCH_PUSHES]
    return t


def hil_search(
    space: Space,
    target: Target,
    pushes: Sequence[Push],
    base_table: dict,
    x0: np.ndarray,
    runner: Runner,
    *,
    seeds: int = 8,
    maxiter: int = 8,
    popsize: int = 10,
    seed: int = 1,
    report: Callable[[str], None] = lambda s: None,
) -> tuple[np.ndarray, float, list[dict]]:
    """Differential evolution over batched hil ensembles (package docstring, step 2); returns (x, score, history)."""
    history: list[dict] = []
    per = seeds + len(SEARCH_PUSHES)
    done = [False]  # some candidate landed in every search and check run
    gen = [0]  # scores() calls so far: the first guess, then one per generation of the evolution
    best_frac = [0.0]  # the best fraction landing of any candidate so far

    def scores(xs: np.ndarray) -> np.ndarray:
        """Per candidate: the mean over its runs of 1 (landed) or CLOSE_WEIGHT x closeness, + the linear margin."""
        fracs: list[float] = []
        ps = [space.params(x) for x in xs]
        lin = [linear_score(p, target) for p in ps]
        tables = []
        for p in ps:
            tables += _search_tables(base_table, p, pushes, seeds) if _shape_ok(p) else []
        res = runner(tables) if tables else []
        out, k = [], 0
        for p, (ls, _) in zip(ps, lin):
            if not _shape_ok(p):
                out.append(-1.0)
                continue
            rr = res[k : k + per]
            k += per
            hits = [_landed(target, p, r) for r in rr]
            part = [
                1.0
                if h
                else (CLOSE_WEIGHT * closeness(target, np.asarray(r["final_alpha"])) if "error" not in r else 0.0)
                for h, r in zip(hits, rr)
            ]
            frac = float(np.mean(hits))
            if all(hits):  # every search run landed: the same again on fresh seeds, so one lucky set is not enough
                check = runner(
                    [_noise(_scene_table(base_table, p, pushes, *NOMINAL_PUSH), CHECK_SEED0 + s) for s in range(per)]
                )
                more = [_landed(target, p, r) for r in check]
                part += [1.0 if h else 0.0 for h in more]
                frac = float(np.mean(hits + more))
                if all(more):
                    done[0] = True
                    part.append(1.0 + FULL_BONUS * len(part))  # (a mean over part: + FULL_BONUS, above any miss)
            gap = max(0.0, min(1.0, ls - 1.0)) if ls > 1 else 0.0
            out.append(float(np.mean(part)) + MARGIN_WEIGHT * gap)
            history.append({"fraction": frac, "linear_gap": gap})
            fracs.append(frac)
        top = max(fracs, default=0.0)
        best_frac[0] = max(best_frac[0], top)
        what = "first guess" if gen[0] == 0 else f"generation {gen[0]}"
        report(
            f"hil search, {what}: {len(xs)} candidate(s) x {per} runs; best of these lands in {top:.3f} "
            f"of its runs (best so far {best_frac[0]:.3f})"
        )
        gen[0] += 1
        return np.array(out)

    s0 = scores(np.array([x0]))[0]
    if done[0]:
        return x0, float(s0), history
    x, s = evolve_around(
        space, x0, s0, scores, lambda: done[0], spread=0.12, popsize=popsize, seed=seed, maxiter=maxiter
    )
    return x, s, history


def evolve_around(
    space: Space,
    x0: np.ndarray,
    s0: float,
    scores: Callable[[np.ndarray], np.ndarray],
    done: Callable[[], bool],
    *,
    spread: float,
    popsize: int,
    seed: int,
    maxiter: int,
    generation: Callable[[float], None] = lambda best: None,
) -> tuple[np.ndarray, float]:
    """(x, score) of the best candidate seen (x0 scoring s0 to begin with): differential evolution (scipy.optimize,
    vectorized: scores(xs) scores the candidates xs (one per row) at once) from x0 and popsize - 1 normal draws
    around it (spread x each bound's width, clipped to the bounds), until done() or maxiter generations;
    generation(best score so far) after each. A chain's hil_search and a sheet's sheet_runs.sheet_search."""
    from scipy.optimize import differential_evolution

    lo = np.array([b[0] for b in space.bounds])
    hi = np.array([b[1] for b in space.bounds])
    rng = np.random.default_rng(seed)
    init = np.clip(x0 + spread * (hi - lo) * rng.standard_normal((popsize, len(lo))), lo, hi)
    init[0] = x0
    best: dict[str, Any] = {"x": x0, "s": s0}

    def f(xt):  # vectorized: xt has shape (dims, candidates)
        sc = scores(xt.T)
        i = int(np.argmax(sc))
        if sc[i] > best["s"]:
            best["x"], best["s"] = xt.T[i].copy(), float(sc[i])
        generation(best["s"])
        return -sc

    def stop(*_a, **_k):
        return done()

    differential_evolution(
        f,
        space.bounds,
        init=init,
        seed=seed,
        maxiter=maxiter,
        polish=False,
        vectorized=True,
        updating="deferred",
        callback=stop,
        tol=0.0,
        atol=-1.0,  # never "converged": a population that all misses alike must keep searching (until maxiter)
    )
    return np.asarray(best["x"]), float(best["s"])


def search_record(search_seeds: int, score: float, candidates: int, hil_runs: int, t0: float, **more: Any) -> dict:
    """design.json's "search" entry (a chain's and a sheet's): the optimizer, the search's seeds, pushes and score,
    the candidates scored, the hil runs, then `more` (a chain's scheduler) and wall_s (time.perf_counter() - t0)."""
    return {
        "optimizer": "scipy.optimize.differential_evolution (linear theory, then batched hil ensembles)",
        "search_seeds": search_seeds,
        "search_pushes": [list(x) for x in SEARCH_PUSHES],
        "search_score": score,
        "candidates_scored": candidates,
        "hil_runs": hil_runs,
        **more,
        "wall_s": time.perf_counter() - t0,
    }
