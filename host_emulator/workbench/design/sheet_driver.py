"""``design(..., sheet="16x16")`` on a square sheet: the first guess, the hil search, the verification of the
written scene.toml (and the lattice's cross-check and the confirmation), design.json and design.png."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from metacell_common.outpaths import check_out_dir
from metacell_common.provenance import provenance

from ...analysis.summary import clean
from ...params import REACTION_KEYS, Params
from ...scene import load_scene, scene_table
from .constants import CONFIRM_SEED0, CROSS_MODEL, NOMINAL_PUSH, REQUIRE
from .scenefile import FIRMWARE_KEYS, assumed_options, assumes_doc
from .search import search_record
from .sheet_landing import LAMBDA_TOL
from .sheet_linear import REST_SHARE_MAX, mode_rest_share, sheet_fastest_modes, sheet_first_guess, sheet_linear_score
from .sheet_runs import sheet_scene, sheet_search, sheet_verify
from .sheet_target import SheetPush, SheetTarget, parse_shape, parse_sheet_pushes, parse_sheet_target
from .space import Space
from .target import DesignError


def sheet_base(scene: str, shape: tuple[int, int]):
    """The base scene (hil) on a square sheet of `shape`: every setting of `scene` but its cells and pushes."""
    try:
        base = load_scene(scene, ["model=hil"])
    except (ValueError, KeyError, OSError) as e:
        raise DesignError(f"--scene {scene!r}: {e}") from None
    per = [k for k in REACTION_KEYS if k in base.params.per_cell_keys]
    if per and base.cells != shape[0] * shape[1]:
        raise DesignError(
            f"--scene {scene!r}: its per-cell {', '.join(per)} do not fit a {shape[0]} x {shape[1]} sheet"
        )
    p = dataclasses.replace(base.params, cells=shape[0] * shape[1], shape=shape, lattice="square", boundary="open")
    return dataclasses.replace(base, cells=p.cells, params=p, perturbations=())


def _chain_twin(sc):
    """The scene on a one-cell chain with the first cell's law and no pushes: what scene_table and the accuracy
    presets read of a sheet's settings (everything but its lattice and its per-cell values)."""
    p = sc.params
    q = dataclasses.replace(
        p, cells=1, shape=(), lattice="chain", boundary="open", **{k: float(p.per_cell(k)[0]) for k in REACTION_KEYS}
    )
    return dataclasses.replace(sc, cells=1, params=q, perturbations=())


def _twin_table(sc) -> dict:
    """scene_table of the chain twin, without the lattice keys a chain's table needs none of."""
    t = scene_table(_chain_twin(sc))
    for k in ("shape", "lattice", "boundary"):
        t["params"].pop(k, None)
    return t


def sheet_table(sc, target: SheetTarget, pushes: Sequence[SheetPush], name: str, description: str) -> dict:
    """The scene.toml table of a designed sheet: `cells = [rows, cols]`, `lattice`, per-cell parameters as rows,
    pushes at (row, col) (the scene format of a sheet)."""
    p: Params = sc.params
    chain = _chain_twin(sc)
    t = _twin_table(sc)
    rows, cols = target.shape
    t["cells"] = [rows, cols]
    t["lattice"] = "square"
    defaults = dataclasses.asdict(Params(cells=1))
    params = {k: v for k, v in t["params"].items() if k in FIRMWARE_KEYS or v != defaults.get(k)}
    for k in REACTION_KEYS:
        v = p.per_cell(k)
        params[k] = [[float(x) for x in r] for r in v.reshape(rows, cols)] if k in p.per_cell_keys else float(v[0])
    for k in FIRMWARE_KEYS:
        params[k] = getattr(p, k)
    t["params"] = params
    t["perturbation"] = [
        {
            "row": q.row,
            "col": q.col,
            "chain": "alpha",
            "torque_Nm": q.sign * NOMINAL_PUSH[0],
            "start_s": 0.1,
            "duration_s": NOMINAL_PUSH[1],
        }
        for q in pushes
    ]
    t.setdefault("model_options", {})["stepper"] = assumed_options(_twin_table(sc), chain.params)["stepper"]
    t["model_options"].pop("noise", None)
    t["model"] = "hil"
    t["name"], t["description"] = name, description
    return t


def _write(path: Path, table: dict, target: SheetTarget) -> None:
    import tomli_w

    head = (
        f"# Scene written by `python -m host_emulator design` (docs/design.md): a {target.shape[0]} x "
        f"{target.shape[1]} sheet, target {target.text()}.\n# Run it: python -m host_emulator run {path}\n"
    )
    t = dict(table)
    params = t.pop("params")
    lines = ["", "[params]"]
    for k, v in params.items():  # a per-cell parameter one row of the sheet per line
        if isinstance(v, list):
            lines += [f"{k} = ["] + ["    [" + ", ".join(repr(float(x)) for x in row) + "]," for row in v] + ["]"]
        else:
            lines.append(tomli_w.dumps({k: v}).rstrip("\n"))
    path.write_text(head + tomli_w.dumps(t) + "\n".join(lines) + "\n")


def design_sheet(
    target: str,
    push: str,
    *,
    sheet: str,
    rest: str | None,
    scene: str = "default",
    vary: Sequence[str] = ("sigma", "k_ab", "k2"),
    seeds: int = 20,
    search_seeds: int = 4,
    maxiter: int = 4,
    require: float = REQUIRE,
    out: str | Path = "out/design_sheet",
    seed: int = 1,
    quiet: bool = True,
) -> dict:
    """Design one law for the pattern region and one for the rest region of a square sheet (docs/design.md,
    "Sheets"); writes design.json, scene.toml and design.png in `out` and returns design.json's content."""
    report = (lambda s: None) if quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    t0 = time.perf_counter()
    shape = parse_shape(sheet)
    tgt = parse_sheet_target(target, shape, rest)
    if not push:
        raise DesignError("--push: a sheet's design needs its pushes, ROWxCOL[:SIGN],... such as 8x4")
    pushes = parse_sheet_pushes(push, tgt)
    vary = tuple(dict.fromkeys(vary))
    bad = [k for k in vary if k not in REACTION_KEYS]
    if bad or not vary:
        raise DesignError(f"--vary {','.join(vary)}: expected names among {', '.join(REACTION_KEYS)}")
    if not (1 <= seeds <= 1000 and 1 <= search_seeds <= 1000 and 0 <= maxiter <= 1000 and 0 < require <= 1):
        raise DesignError("seeds and search seeds in 1..1000, maxiter in 0..1000, require in (0, 1]")
    base = sheet_base(scene, shape)
    outp = Path(out)
    why = check_out_dir(outp)
    if why:
        raise DesignError(why)
    space = Space(base.params, vary, vary, tgt.segments())  # every varied parameter: one value per region
    report(f"design {tgt.text()} on a {shape[0]} x {shape[1]} sheet: linear theory over {', '.join(space.names)}")
    x_lin, lin, _ = sheet_first_guess(space, tgt, seed)
    report(f"first guess: linear score {lin:.3f} (> 1: the pattern law grows, the rest law decays)")
    x, score, hist, runs = sheet_search(
        space, tgt, pushes, base, x_lin, seeds=search_seeds, maxiter=maxiter, seed=seed, report=report
    )
    p = space.params(x)
    lin2, facts = sheet_linear_score(p, tgt)
    modes = sheet_fastest_modes(p, 2)  # the whole sheet's eigenproblem with the designed per-cell laws
    check: dict[str, Any] = {
        "growth_per_s": [m["growth_per_s"] for m in modes],
        "kind": modes[0]["kind"],
        "rest_share": mode_rest_share(modes[0]["alpha"], tgt),
        "rest_share_max": REST_SHARE_MAX,
    }
    name = f"design_sheet_{shape[0]}x{shape[1]}"
    desc = (
        f"designed for {tgt.text()} on a {shape[0]} x {shape[1]} square sheet with push(es) on "
        + ", ".join(f"alpha at ({q.row}, {q.col}) ({'CCW' if q.sign > 0 else 'CW'})" for q in pushes)
        + " (python -m host_emulator design, docs/design.md)"
    )
    outp.mkdir(parents=True, exist_ok=True)
    scene_path = outp / "scene.toml"
    built = sheet_scene(dataclasses.replace(base, name=name, description=desc), p, pushes, *NOMINAL_PUSH, None)
    _write(scene_path, sheet_table(built, tgt, pushes, name, desc), tgt)
    vscene = load_scene(str(scene_path))  # the written file as `run` loads it
    report(f"verifying: {seeds} noise seeds and the push range")
    ver = sheet_verify(vscene, tgt, seeds)
    report(f"cross-check in {CROSS_MODEL}: the same {seeds} draws")
    cross = sheet_verify(vscene, tgt, seeds, pushes_too=False, model=CROSS_MODEL)
    report(f"confirming on {seeds} fresh draws")
    c = sheet_verify(vscene, tgt, seeds, pushes_too=False, seed0=CONFIRM_SEED0)
    pooled = (ver["fraction_seeds"] + c["fraction_seeds"]) / 2
    runs += len(ver["runs"]) + len(cross["runs"]) + len(c["runs"])
    doc: dict[str, Any] = {
        "target": tgt.text(),
        "target_kind": "sheet",
        "sheet": list(shape),
        "lattice": "square",
        "lambda_cells": tgt.lam,
        "lambda_tolerance": LAMBDA_TOL if tgt.lam is not None else None,
        "rest": tgt.rest_text,
        "rest_cells": list(tgt.rest),
        "cells": p.cells,
        "pushes": [{"row": q.row, "col": q.col, "sign": q.sign} for q in pushes],
        "push_text": ",".join(f"{q.row}x{q.col}:{'+' if q.sign > 0 else '-'}" for q in pushes),
        "push_nominal": {"torque_Nm": NOMINAL_PUSH[0], "duration_s": NOMINAL_PUSH[1], "start_s": 0.1},
        "base_scene": scene,
        "vary": list(vary),
        "per_cell": list(vary),
        "regions": {
            "pattern": {k: float(p.per_cell(k)[~tgt.rest_mask()][0]) for k in REACTION_KEYS},
            "rest": {k: float(p.per_cell(k)[tgt.rest_mask()][0]) for k in REACTION_KEYS},
        },
        "linear_theory": {
            "theory": "hil: each region's law on the square lattice (inertia + the motors' back-EMF damping); "
            "whole_sheet: the sheet's eigenproblem with the designed per-cell laws (analysis.sheet_modes)",
            "score": lin2,
            "first_guess_score": lin,
            **facts,
            "whole_sheet": check,
        },
        "verification": ver,
        "cross_check": cross,
        "confirmation": {
            "seeds": seeds,
            "seed0": CONFIRM_SEED0,
            "fraction_seeds": c["fraction_seeds"],
            "pooled": pooled,
            "runs": c["runs"],
        },
        "assumes": assumes_doc(_twin_table(base), p),
        "reached": bool(pooled >= require),
        "require": require,
        "nearest_reachable": None,
        "search": search_record(search_seeds, score, len(hist), runs, t0),
        "files": ["design.json", "scene.toml", "design.png"],
        "provenance": provenance(),
    }
    plot_sheet_design(doc, tgt, p, outp / "design.png")
    doc = clean(doc)
    (outp / "design.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return doc


def plot_sheet_design(doc: dict, target: SheetTarget, p: Params, path: Path) -> None:
    """design.png of a sheet: the final alpha of the first verification draw, the fraction of draws in which
    each cell ended beyond 0.1 rad, and the designed sigma per cell (the rest region outlined)."""
    from matplotlib.figure import Figure

    runs = [r for r in doc["verification"]["runs"] if "final_alpha_rad" in r]
    fig = Figure(figsize=(12, 4))
    axs = fig.subplots(1, 3)
    first = target.topology.grid(np.asarray(runs[0]["final_alpha_rad"])) if runs else np.zeros(target.shape)
    moved = np.mean([np.abs(np.asarray(r["final_alpha_rad"])) > 0.1 for r in runs], axis=0) if runs else None
    panels = [
        (first, "final alpha (rad), first noise draw", "RdBu_r", (-0.8, 0.8)),
        (
            target.topology.grid(moved) if moved is not None else first * 0,
            "share of runs beyond 0.1 rad",
            "viridis",
            (0, 1),
        ),
        (target.topology.grid(p.per_cell("sigma")), "sigma (N m/rad)", "magma", (None, None)),
    ]
    rest = target.topology.grid(target.rest_mask().astype(float))
    for ax, (g, title, cmap, (lo, hi)) in zip(axs, panels):
        im = ax.imshow(
            g,
            cmap=cmap,
            vmin=lo,
            vmax=hi,
            origin="upper",
            extent=(0.5, target.shape[1] + 0.5, target.shape[0] + 0.5, 0.5),
        )
        ax.contour(
            np.arange(1, target.shape[1] + 1),
            np.arange(1, target.shape[0] + 1),
            rest,
            levels=[0.5],
            colors="k",
            linewidths=1.2,
        )
        for q in doc["pushes"]:
            ax.plot(q["col"], q["row"], "k+", ms=8)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("col")
        ax.set_ylabel("row")
        fig.colorbar(im, ax=ax, shrink=0.8)
    v = doc["verification"]
    fig.suptitle(
        f"target {target.text()} ({target.shape[0]} x {target.shape[1]}), push {doc['push_text']}: lands in "
        f"{100 * v['fraction_seeds']:.0f} % of {v['seeds']} noise seeds, {100 * (v['fraction_pushes'] or 0):.0f} % "
        "of the pushes (hil)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
