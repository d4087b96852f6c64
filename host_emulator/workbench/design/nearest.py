"""An unreachable target's nearest reachable one: the neighbouring wall counts or layouts, each designed and
verified in turn."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ...params import Params
from .constants import MAX_NEAREST_VERIFIED
from .ensembles import Runner
from .linear import first_guess
from .scenefile import _params_doc, _write_scene
from .search import hil_search
from .space import space_for
from .target import Target
from .verification import verify


def _neighbours(t: Target, cells: int) -> list[Target]:
    """Targets near t, nearest first: every other wall count by its wavelength's distance; the layouts with one
    wall moved by one or two bonds (one bond first)."""
    if t.kind == "lambda":
        zs = sorted((z for z in range(1, cells) if z != t.z), key=lambda z: abs(2 * (cells - 1) / z - (t.lam or 0)))
        return [Target("lambda", z, (), 2 * (cells - 1) / z, (), cells) for z in zs]
    out = []
    for step in (1.0, 2.0):
        for i in range(len(t.walls)):
            for d in (-step, step):
                w = list(t.walls)
                w[i] += d
                if (
                    1.5 <= w[i] <= cells - 0.5
                    and len(set(w)) == len(w)
                    and not any(abs(c - x) < 1 for c in t.rest for x in w)
                ):
                    out.append(Target("walls", len(w), tuple(sorted(w)), None, t.rest, cells))
    return list(dict.fromkeys(out))


def nearest_reachable(
    target: Target,
    base: Params,
    vary,
    per_cell,
    pushes,
    base_table: dict,
    runner: Runner,
    outp: Path,
    *,
    seeds: int,
    require: float,
    seed: int,
    report: Callable[[str], None],
    search_seeds: int = 8,
    maxiter: int = 8,
) -> dict | None:
    """The nearest target (_neighbours' order) whose linear first guess has the target's mode (score > 1) and whose
    design (first guess, then the hil search) lands in `require` of `seeds` noise seeds; its scene is left as
    nearest_scene.toml. None if none of the first MAX_NEAREST_VERIFIED such candidates does."""
    verified = 0
    for cand in _neighbours(target, target.cells):
        sp = space_for(base, vary, per_cell, cand)
        xc, lc, _ = first_guess(sp, cand, seed)
        if lc <= 1.0:
            report(f"nearest: {cand.text()} has no linear first guess (score {lc:.2f})")
            continue
        xc, _, _ = hil_search(
            sp, cand, pushes, base_table, xc, runner, seeds=search_seeds, maxiter=maxiter, seed=seed, report=report
        )
        pc = sp.params(xc)
        cpath = outp / "nearest_scene.toml"
        _write_scene(cpath, base_table, pc, pushes, cand, "nearest_" + cand.text().replace("=", "_"))
        vc = verify(cpath, cand, runner, seeds, pushes_too=False)
        verified += 1
        report(f"nearest: {cand.text()} lands in {vc['fraction_seeds']:.2f} of the seeds")
        if vc["fraction_seeds"] >= require:
            return {
                "target": cand.text(),
                "fraction_seeds": vc["fraction_seeds"],
                "params": _params_doc(pc),
                "scene": cpath.name,
            }
        cpath.unlink()
        if verified >= MAX_NEAREST_VERIFIED:
            break
    return None
