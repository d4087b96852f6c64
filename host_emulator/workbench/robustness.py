"""`python -m host_emulator robustness`: how many noise seeds and hand pushes select the source's result, per paper
scene (docs/band-stiffness.md#robustness-of-the-sources-results)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

from ..construct import scene_cost
from ..limits import batch_budget
from ..models.options import RIG_UNCERTAINTY, rig_noise_overrides
from ..outpaths import check_out_dir
from ..progress import bar
from ..scene import load_scene
from .paper import _BAR, NOISE, PERIOD_TOL, SOURCE_PERIOD_S, _json_default, _noise_sets, _run, aligned

# scene -> (model, the source's result: Z domain walls, "rest", or an oscillation period in s)
ROBUST_SCENES = {
    "exp1_ccw_ccw": ("hil", 2),
    "exp2_ccw_cw": ("hil", 3),
    "exp3_single_sigma9": ("hil", 4),
    "exp3_single_sigma6": ("hil", 2),
    "exp3_single_sigma14": ("lattice", SOURCE_PERIOD_S),
    "exp4_stable_eta10": ("hil", "rest"),
    "exp5_rest": ("hil", "rest"),
}
ROBUST_TORQUES_NM = (0.005, 0.01, 0.02, 0.04)  # a light to a firm push by hand (the motors' stall torque is 0.044)
ROBUST_DURATIONS_S = (0.05, 0.1, 0.2)
ROBUST_JITTER_COUNTS = 0.5


def selects(o: dict, want: object) -> bool:
    """Does a run's observables show the source's result `want` (Z walls, "rest", or a period in s)?"""
    if want == "rest":
        return bool(o["at_rest"])
    if isinstance(want, float):
        p = o["oscillation_period_s"]
        return bool(p is not None and abs(p - want) <= PERIOD_TOL * want)
    return bool(not o["at_rest"] and o["domain_walls"] == want)


def seed_fractions(
    name: str, sets: Sequence[str], want: object, seeds: int, *, jitter: bool = True
) -> tuple[float, float | None]:
    """(fraction of `seeds` noise seeds whose run of scene `name` with `sets` selects `want`, the same with
    ROBUST_JITTER_COUNTS of encoder jitter, None without jitter); seeds 2000, 2001, ... as robustness uses them."""
    out: list[float | None] = []
    for extra in ({}, {"encoder_jitter_counts": ROBUST_JITTER_COUNTS}):
        if extra and not jitter:
            out.append(None)
            continue
        hits = 0
        for s in range(seeds):
            noise = _noise_sets(2000 + s) + [f"model_options.noise.{k}={v}" for k, v in extra.items()]
            hits += selects(_run(name, list(sets) + noise)[2], want)
        out.append(hits / seeds)
    return float(out[0] or 0.0), out[1]


def _push_sets(scene, torque, duration):
    """Overrides giving every perturbation of the scene this magnitude (its sign kept) and duration."""
    out = []
    for i, q in enumerate(scene.perturbations):
        sign = 1.0 if q.torque_Nm >= 0 else -1.0
        out += [f"perturbation.{i + 1}.torque_Nm={sign * torque}", f"perturbation.{i + 1}.duration_s={duration}"]
    return out


def robustness(
    seeds: int = 20,
    torques: Sequence[float] = ROBUST_TORQUES_NM,
    durations: Sequence[float] = ROBUST_DURATIONS_S,
    scenes: Sequence[str] | None = None,
    *,
    quiet: bool = True,
) -> dict:
    """Per scene: the fraction of noise seeds (5 % band and viscosity spread; the same with encoder jitter; and draws
    of the rig's uncertainty, docs/physics.md#the-rigs-uncertainty) and of hand pushes (every torque x duration, no
    noise) that select the source's result. quiet=False: a progress bar (one step per run) on a terminal."""
    names = list(scenes or ROBUST_SCENES)
    total = 0
    for name in names:
        model = ROBUST_SCENES[name][0]
        total += seeds * (3 if model == "hil" else 2)
        total += len(torques) * len(durations) if load_scene(name).perturbations else 0
    _BAR[0] = bar(total, desc="robustness", unit="run", quiet=quiet)
    try:
        return _robustness(names, seeds, torques, durations)
    finally:
        _BAR[0].close()
        _BAR[0] = None


def _robustness(names, seeds, torques, durations) -> dict:
    out = {}
    for name in names:
        model, want = ROBUST_SCENES[name]
        base = [f"model={model}"]
        row: dict = {"model": model, "source": want}
        row["seeds"], row["seeds_jitter"] = seed_fractions(name, base, want, seeds, jitter=model == "hil")
        # the rig's uncertainty: band, viscosity, inertia, push magnitude and timing drawn (the same seeds as design)
        row["seeds_rig"] = (
            sum(selects(_run(name, base + rig_noise_overrides(2000 + s))[2], want) for s in range(seeds)) / seeds
        )
        scene = load_scene(name, base)
        grid = {}
        if scene.perturbations:
            hit = {
                (tq, du): selects(_run(name, base + _push_sets(scene, tq, du))[2], want)
                for tq in torques
                for du in durations
            }
            grid = {f"{tq * 1e3:g} mN*m x {du:g} s": v for (tq, du), v in hit.items()}
            row["pushes"] = sum(hit.values()) / len(hit)
            ok = [tq for tq in torques if all(hit[(tq, du)] for du in durations)]
            row["min_push_Nm"] = min(ok) if ok else None
        else:
            row["pushes"] = None
        row["push_grid"] = grid
        out[name] = row
    return out


def robustness_budget(
    seeds: int,
    scenes: Sequence[str] | None = None,
    torques: Sequence[float] = ROBUST_TORQUES_NM,
    durations: Sequence[float] = ROBUST_DURATIONS_S,
) -> str | None:
    """robustness's runs (per scene: seeds, seeds with jitter on hil, every push) x their cost, against the batch
    limit, before any run: one line with the figure, or None."""
    total = 0.0
    for name in scenes or ROBUST_SCENES:
        model, _ = ROBUST_SCENES[name]
        scene = load_scene(name, [f"model={model}"])
        runs = seeds * (3 if model == "hil" else 2) + (len(torques) * len(durations) if scene.perturbations else 0)
        total += runs * scene_cost(scene)
    return batch_budget(total, f"robustness --seeds {seeds}")


def print_robustness(res: dict, seeds: int, file: TextIO = sys.stdout) -> None:
    def pct(v):
        return "-" if v is None else f"{100 * v:.0f} %"

    rows = []
    for name, r in res.items():
        src = (
            f"Z={r['source']}"
            if isinstance(r["source"], int)
            else (f"{r['source']:g} s" if isinstance(r["source"], float) else str(r["source"]))
        )
        mp = r.get("min_push_Nm")
        rows.append(
            [
                name,
                r["model"],
                src,
                pct(r["seeds"]),
                pct(r["seeds_jitter"]),
                pct(r["seeds_rig"]),
                pct(r["pushes"]),
                "-" if mp is None else f"{mp * 1e3:g} mN*m",
            ]
        )
    head = ["scene", "model", "source", "seeds", "+jitter", "rig", "pushes", "min push"]
    for ln in aligned(rows, head, right=(3, 4, 5, 6)):
        print(ln, file=file)
    print(
        "legend: source = the source's result (Z domain walls, rest, or an oscillation period);\n"
        f"        seeds = the fraction of {seeds} noise seeds (5 % spread of band stiffness and honey viscosity) "
        "selecting it;\n"
        f"        +jitter = the same with {ROBUST_JITTER_COUNTS} count rms encoder jitter (hil only);\n"
        f"        rig = the fraction of {seeds} draws of the rig's uncertainty (bands x[0.85, 1.15], viscosity "
        "x[0.7, 1.3], inertia x[0.9, 1.1],\n"
        "              push x[0.7, 1.3] and +-50 ms; docs/physics.md#the-rigs-uncertainty) selecting it;\n"
        f"        pushes = the fraction of {len(ROBUST_TORQUES_NM)} torques x {len(ROBUST_DURATIONS_S)} durations "
        "(no noise) selecting it;\n"
        "        min push = the smallest torque that selects it at every duration.",
        file=file,
    )


def robustness_main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator robustness",
        description="Fraction of noise seeds and of hand pushes that select the source's result, per paper scene.",
        epilog="example: python -m host_emulator robustness --seeds 20 --out out/robust",
    )
    ap.add_argument("--seeds", type=int, default=20, help="noise seeds per scene (default 20)")
    ap.add_argument(
        "--scene",
        action="append",
        default=None,
        choices=sorted(ROBUST_SCENES),
        help="only this scene (repeatable; default all paper scenes)",
    )
    ap.add_argument("--out", default=None, help="directory for robustness.json (default: print only)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar (it shows on a terminal only anyway)")
    args = ap.parse_args(argv)
    if not 1 <= args.seeds <= 10000:
        print(f"robustness: error: --seeds {args.seeds}: must be in 1..10000", file=sys.stderr)
        return 2
    problem = (check_out_dir(args.out) if args.out else None) or robustness_budget(args.seeds, args.scene)
    if problem:
        print(f"robustness: error: {problem}", file=sys.stderr)
        return 2
    res = robustness(args.seeds, scenes=args.scene, quiet=args.quiet)
    print_robustness(res, args.seeds)
    if args.out:
        out = Path(args.out)
        doc = {
            "seeds": args.seeds,
            "noise": NOISE,
            "jitter_counts": ROBUST_JITTER_COUNTS,
            "rig_uncertainty": RIG_UNCERTAINTY,
            "torques_Nm": list(ROBUST_TORQUES_NM),
            "durations_s": list(ROBUST_DURATIONS_S),
            "scenes": res,
        }
        (out / "robustness.json").write_text(json.dumps(doc, indent=2, default=_json_default) + "\n")
        print(f"wrote {out}/robustness.json")
    return 0
