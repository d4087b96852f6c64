"""``design(...)``: the three steps in order (first guess, hil search, verification), the nearest reachable target
when it falls short, and design.json."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from metacell_common.outpaths import check_out_dir
from metacell_common.provenance import provenance

from ...analysis.summary import clean
from ...params import REACTION_KEYS
from ...scene import load_scene, scene_table
from .constants import (
    CONFIRM_SEED0,
    CROSS_MODEL,
    NOMINAL_PUSH,
    PUSH_DURATIONS_S,
    PUSH_TORQUES_NM,
    REQUIRE,
)
from .ensembles import Runner
from .linear import first_guess, linear_score
from .nearest import nearest_reachable
from .plot import plot_design
from .scenefile import _params_doc, _write_scene, assumes_doc
from .search import hil_search, search_record
from .space import Space
from .target import DesignError, Push, parse_pushes, parse_target
from .verification import verify


def design(
    target: str,
    push: str | Sequence[int] | None = None,
    *,
    scene: str = "default",
    vary: Sequence[str] = ("sigma", "k_ab", "k2"),
    per_cell: Sequence[str] | None = None,
    rest: str | Sequence[int] | None = None,
    seeds: int = 20,
    search_seeds: int | None = None,
    maxiter: int | None = None,
    require: float = REQUIRE,
    nearest: bool = True,
    out: str | Path | None = None,
    scheduler: str | None = None,
    seed: int = 1,
    quiet: bool = True,
    sheet: str | None = None,
) -> dict:
    """Design parameters for a target pattern (the package docstring); writes design.json, scene.toml and design.png in
    `out` and returns design.json's content. per_cell None: none for a wavelength, sigma and k2 for a wall layout.
    sheet "ROWSxCOLS": a square sheet's design (sheet_driver.design_sheet, as `design --sheet`: push ROWxCOL,
    rest a region; search seeds and generations 4 by default, 8 on a chain; out out/design_sheet, else out/design).
    Raises DesignError (bad input)."""
    if sheet is not None:
        from .sheet_driver import design_sheet

        for name, given in (("per_cell", per_cell), ("scheduler", scheduler)):
            if given is not None:  # a sheet's ensembles run in this process; every varied parameter is per region
                raise DesignError(f"{name} is for a chain's design, not with sheet")
        if push is not None and not isinstance(push, str):
            raise DesignError("push: a sheet's pushes are text, ROWxCOL[:SIGN],... such as 8x4")
        return design_sheet(
            target,
            push or "",
            sheet=sheet,
            rest=rest if rest is None or isinstance(rest, str) else ",".join(map(str, rest)),
            scene=scene,
            vary=vary,
            seeds=seeds,
            search_seeds=4 if search_seeds is None else search_seeds,
            maxiter=4 if maxiter is None else maxiter,
            require=require,
            out="out/design_sheet" if out is None else out,
            seed=seed,
            quiet=quiet,
        )
    search_seeds = 8 if search_seeds is None else search_seeds
    maxiter = 8 if maxiter is None else maxiter
    out = "out/design" if out is None else out
    report = (lambda s: None) if quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    t0 = time.perf_counter()
    try:
        base = load_scene(scene, ["model=hil"])
    except (ValueError, KeyError, OSError) as e:
        raise DesignError(f"--scene {scene!r}: {e}") from None
    n = base.cells
    tgt = parse_target(target, n, rest)
    if push is None:
        pushes = tuple(Push(q.cell, 1 if q.torque_Nm >= 0 else -1) for q in base.perturbations if q.chain == "alpha")
        if not pushes:
            raise DesignError(f"--push: scene {scene!r} has no push on alpha; give --push CELL[:SIGN],...")
    else:
        pushes = parse_pushes(push, n)
    vary = tuple(dict.fromkeys(vary))
    bad = [k for k in vary if k not in REACTION_KEYS]
    if bad or not vary:
        raise DesignError(f"--vary {','.join(vary)}: expected names among {', '.join(REACTION_KEYS)}")
    if per_cell is None:
        per_cell = (
            () if tgt.kind == "lambda" and not tgt.rest else tuple(k for k in ("sigma", "k_ab", "k2") if k in vary)
        )
    per_cell = tuple(dict.fromkeys(per_cell))
    if any(k not in vary for k in per_cell):
        raise DesignError(f"--per-cell {','.join(per_cell)}: each must also be in --vary ({','.join(vary)})")
    if not (1 <= seeds <= 1000 and 1 <= search_seeds <= 1000 and 0 <= maxiter <= 1000 and 0 < require <= 1):
        raise DesignError("seeds and search seeds in 1..1000, maxiter in 0..1000, require in (0, 1]")
    if scheduler:  # not an address, not Dask, nobody there: one line, before --out is created
        from ..sweep.cluster import check_scheduler
        from ..sweep.errors import SweepError, SweepFailed

        try:
            scheduler = check_scheduler(scheduler)
        except (SweepError, SweepFailed) as e:
            raise DesignError(str(e)) from None
    outp = Path(out)
    why = check_out_dir(outp)
    if why:
        raise DesignError(why)
    base_table = scene_table(base)
    base_table["model"] = "hil"
    runner = Runner(scheduler)
    try:
        space = Space(base.params, vary, per_cell, tgt.segments())
        report(f"design {tgt.text()}: linear theory over {', '.join(space.names)}")
        x_lin, lin, facts = first_guess(space, tgt, seed)
        report(f"first guess: linear score {lin:.3f} (> 1: the fastest mode has the target's walls)")
        x, score, hist = hil_search(
            space,
            tgt,
            pushes,
            base_table,
            x_lin,
            runner,
            seeds=search_seeds,
            maxiter=maxiter,
            seed=seed,
            report=report,
        )
        p = space.params(x)
        lin2, facts2 = linear_score(p, tgt)
        name = "design_" + tgt.text().replace("=", "_").replace(",", "_").replace(" ", "_")
        scene_path = outp / "scene.toml"
        _write_scene(scene_path, base_table, p, pushes, tgt, name)
        report(f"verifying {scene_path}: {seeds} noise seeds and {len(PUSH_TORQUES_NM) * len(PUSH_DURATIONS_S)} pushes")
        ver = verify(scene_path, tgt, runner, seeds)
        report(f"cross-check in {CROSS_MODEL}: the same {seeds} draws")
        cross = verify(scene_path, tgt, runner, seeds, pushes_too=False, model=CROSS_MODEL)
        # 20 draws are a noisy estimate of the rate: as many fresh ones, and the target is reached when all of them
        # together land in >= require (a design verified at 90 % by luck is not reported reached)
        report(f"confirming on {seeds} fresh draws")
        c = verify(scene_path, tgt, runner, seeds, pushes_too=False, seed0=CONFIRM_SEED0)
        pooled = (ver["fraction_seeds"] + c["fraction_seeds"]) / 2
        confirm = {"seeds": seeds, "seed0": CONFIRM_SEED0, "fraction_seeds": c["fraction_seeds"], "pooled": pooled}
        reached = bool(pooled >= require)
        near = None
        if not reached and nearest:
            near = nearest_reachable(
                tgt,
                base.params,
                vary,
                per_cell,
                pushes,
                base_table,
                runner,
                outp,
                seeds=seeds,
                require=require,
                seed=seed,
                report=report,
                search_seeds=search_seeds,
                maxiter=maxiter,
            )
        doc: dict[str, Any] = {
            "target": tgt.text(),
            "target_kind": tgt.kind,
            "domain_walls": tgt.z,
            "walls": list(tgt.walls) if tgt.kind == "walls" else None,
            "lambda_cells": tgt.lam,
            "rest_cells": list(tgt.rest),
            "cells": n,
            "pushes": [{"cell": q.cell, "sign": q.sign} for q in pushes],
            "push_text": ",".join(f"{q.cell}:{'+' if q.sign > 0 else '-'}" for q in pushes),
            "push_nominal": {"torque_Nm": NOMINAL_PUSH[0], "duration_s": NOMINAL_PUSH[1], "start_s": 0.1},
            "base_scene": base.name,
            "vary": list(vary),
            "per_cell": list(per_cell),
            "segments": [int(s) + 1 for s in tgt.segments()],
            "params": _params_doc(p),
            "linear_theory": {
                "theory": "hil: eigenmodes of the chain, lattice with inertia + the motors' back-EMF damping",
                "score": lin2,
                "first_guess_score": lin,
                "growth_per_s": facts2.get("growth_per_s"),
                "next_growth_per_s": facts2.get("next_growth_per_s"),
                "kind": facts2.get("kind"),
                "mode_walls": facts2.get("walls"),
                "mode_alpha": facts2.get("mode_alpha"),
            },
            "verification": ver,
            "cross_check": cross,
            "confirmation": confirm,
            "assumes": assumes_doc(base_table, p),
            "reached": reached,
            "require": require,
            "nearest_reachable": near,
            "search": search_record(search_seeds, score, len(hist), runner.runs, t0, scheduler=scheduler),
            "files": ["design.json", "scene.toml", "design.png"] + (["nearest_scene.toml"] if near else []),
            "provenance": provenance(),
        }
    finally:
        runner.close()
    plot_design(doc, tgt, outp / "design.png")
    doc = clean(doc)
    (outp / "design.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return doc
