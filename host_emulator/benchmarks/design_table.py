"""The design table of docs/design.md: `design`'s verified success over every wavelength that fits the chain and over
random wall layouts.

    python -m host_emulator.benchmarks.design_table --out out/design_table      # about 15 minutes on one core

Every target is designed with the command's defaults (push on cell 8, 20 verification draws of the rig's uncertainty,
the documented push range) and verified by running its scene.toml (host_emulator.workbench.design), in hil and, with
the same draws, in the lattice (the cross-model check); its scene.toml is then run again in hil on 20 fresh draws
(seeds 9000..) and on the verification's draws with back-EMF compensation on. `--target TARGET@PUSH` (repeatable)
designs those instead:

    python -m host_emulator.benchmarks.design_table --out out/design_five --target lambda=7.5@6,10 \
        --target lambda=10@8 --target walls=4.5,11.5@6,10 --target walls=2.5,10.5,14.5@8 --target walls=5.5,10.5@8

Wavelengths: lambda = 2 (n - 1) / Z for Z = 1 .. n - 1 walls. Wall layouts: `--layouts` of them drawn with numpy's
default_rng(`--seed`): 1 to 4 walls on bonds 1.5 .. n - 0.5, consecutive walls at least `--spacing` cells apart.
Prints a markdown table per family (target, verified fraction of seeds and of pushes, the lattice's, the
confirmation's and whether the target is reached, the fresh draws' and back-EMF compensation's, why the most common
miss among the seeds missed and its walls, runs, wall time) and writes design_table.json and every design's
directory under --out.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np


def wall_layouts(count: int, cells: int = 16, spacing: int = 3, seed: int = 23) -> list[tuple[float, ...]]:
    """`count` distinct layouts on bonds j + 0.5 (1 <= j <= cells - 1), consecutive walls >= spacing apart, drawn
    with default_rng(seed): the number of walls uniform in 1..4, then their bonds uniform among the layouts that
    keep the spacing (rejection sampling), sorted."""
    rng = np.random.default_rng(seed)
    out: list[tuple[float, ...]] = []
    while len(out) < count:
        z = int(rng.integers(1, 5))
        while True:
            w = tuple(sorted(float(j) + 0.5 for j in rng.choice(np.arange(1, cells), size=z, replace=False)))
            if all(b - a >= spacing for a, b in zip(w[:-1], w[1:])):
                break
        if w not in out:
            out.append(w)
    return out


def band_scan(n: int = 16, points: tuple[int, int, int] = (25, 26, 26)) -> dict:
    """The fastest free-end mode a uniform chain can have within the firmware's gains: over a grid of k_ab in
    0.005..0.25, k2 in -0.25..0, sigma in 0..0.25 (N m/rad), the hil theory's growth rates at kappa = pi m / n;
    counts, per m, the laws whose fastest mode is m, stationary and growing faster than 1/s."""
    from ..analysis.stability import growth_rates, motor_damping
    from ..params import Params

    p0 = Params(cells=n)
    km = np.pi * np.arange(n) / n
    count: Counter = Counter()
    total = 0
    for kab in np.linspace(0.005, 0.25, points[0]):
        for k2 in np.linspace(-0.25, 0.0, points[1]):
            for sig in np.linspace(0.0, 0.25, points[2]):
                p = p0.with_overrides(k_ab=float(kab), k2=float(k2), sigma=float(sig))
                g = growth_rates(p, km, inertia=True, motor_damping=motor_damping(p))[:, 0]
                m = int(np.argmax(g.real))
                total += 1
                if g[m].real > 1.0 and abs(g[m].imag) < 1e-9:
                    count[m] += 1
    return {"laws": total, "fastest_mode_counts": dict(sorted(count.items())), "largest_m": max(count)}


FRESH_SEED0 = 9000  # fresh draws: seeds neither the search (3000.., 4000..) nor the verification (2000..) used


def rechecks(out: Path, target: str, seeds: int) -> tuple[float, float]:
    """(fraction of `seeds` fresh draws of the rig's uncertainty (FRESH_SEED0..) landing when the design's scene.toml
    runs in hil again; fraction of the verification's draws (the same seeds) landing with the firmware's back-EMF
    compensation on (params.bemf_comp = true), a configuration the design does not assume)."""
    from ..workbench.design import Runner, parse_target, verify

    tgt, sc = parse_target(target), out / "scene.toml"
    fresh = verify(sc, tgt, Runner(), seeds, pushes_too=False, seed0=FRESH_SEED0)
    bemf = verify(sc, tgt, Runner(), seeds, pushes_too=False, overrides=["params.bemf_comp=true"])
    return float(fresh["fraction_seeds"]), float(bemf["fraction_seeds"])


def _row(target: str, doc: dict, wall_s: float, again: tuple[float, float]) -> dict:
    v = doc["verification"]
    missed = Counter(
        (r.get("why") or "error", tuple(r.get("walls", ()))) for r in v["runs"][: v["seeds"]] if not r["landed"]
    )
    return {
        "target": target,
        "fraction_seeds": v["fraction_seeds"],
        "fraction_pushes": v["fraction_pushes"],
        "cross_model": doc["cross_check"]["model"],
        "fraction_cross": doc["cross_check"]["fraction_seeds"],
        "fraction_fresh": again[0],
        "fraction_bemf_on": again[1],
        "push": doc["push_text"],
        "reached": doc["reached"],
        "fraction_confirm": (doc.get("confirmation") or {}).get("fraction_seeds"),
        "missed": [{"why": k[0], "walls": list(k[1]), "runs": c} for k, c in missed.most_common(1)],
        "linear_score": doc["linear_theory"]["score"],
        "first_guess_score": doc["linear_theory"]["first_guess_score"],
        "params": doc["params"],
        "per_cell": doc["per_cell"],
        "hil_runs": doc["search"]["hil_runs"],
        "wall_s": wall_s,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.design_table", description=__doc__)
    ap.add_argument("--out", default="out/design_table", help="directory for design_table.json and the designs")
    ap.add_argument("--layouts", type=int, default=20, help="random wall layouts (default 20)")
    ap.add_argument("--spacing", type=int, default=3, help="least distance between walls, cells (default 3)")
    ap.add_argument("--seed", type=int, default=23, help="seed of the layouts (default 23)")
    ap.add_argument("--push", default="8", help="pushes of every design (default 8)")
    ap.add_argument("--only", choices=("lambda", "walls"), default=None, help="one family only")
    ap.add_argument(
        "--target",
        action="append",
        default=None,
        metavar="TARGET[@PUSH]",
        help="design these targets only (repeatable), each with its own pushes after @ (default --push), e.g. "
        "walls=4.5,11.5@6,10; the rows form one table",
    )
    ap.add_argument(
        "--band-scan", action="store_true", help="only the scan of the firmware's gain box for the fastest mode"
    )
    args = ap.parse_args(argv)
    if args.band_scan:
        res = band_scan()
        print(
            f"{res['laws']} uniform laws in the firmware's gain box; laws whose fastest free-end mode is stationary "
            f"and grows, by mode index m: {res['fastest_mode_counts']}; largest m = {res['largest_m']} "
            f"(cosine wavelength {2 * 16 / res['largest_m']:.3g} cells)"
        )
        return 0
    from ..outpaths import check_out_dir
    from ..workbench.design import design

    out = Path(args.out)
    why = check_out_dir(out)
    if why:
        print(f"design_table: error: {why}", file=sys.stderr)
        return 2
    n = 16
    targets: list[tuple[str, str, str]] = []  # (family, target, pushes)
    if args.target:
        for spec in args.target:
            tgt, _, push = spec.partition("@")
            targets.append(("given", tgt, push or args.push))
    if args.only in (None, "lambda") and not args.target:
        targets += [("lambda", f"lambda={2 * (n - 1) / z:.6g}", args.push) for z in range(1, n)]
    if args.only in (None, "walls") and not args.target:
        targets += [
            ("walls", "walls=" + ",".join(f"{w:g}" for w in lay), args.push)
            for lay in wall_layouts(args.layouts, n, args.spacing, args.seed)
        ]
    rows = []
    t_all = time.perf_counter()
    for fam, tgt, push in targets:
        t0 = time.perf_counter()
        name = tgt + ("" if push == args.push else "_push_" + push)
        where = out / name.replace("=", "_").replace(",", "_").replace(":", "")
        try:
            d = design(tgt, push, out=where, nearest=False)
        except ValueError as e:  # DesignError: a bad --target
            print(f"design_table: error: {tgt}@{push}: {e}", file=sys.stderr)
            return 2
        wall = time.perf_counter() - t0
        rows.append({"family": fam, **_row(tgt, d, wall, rechecks(where, tgt, d["verification"]["seeds"]))})
        r = rows[-1]
        print(
            f"{tgt:28s} seeds {100 * r['fraction_seeds']:5.0f} %  {r['cross_model']} "
            f"{100 * r['fraction_cross']:5.0f} %  fresh {100 * r['fraction_fresh']:5.0f} %  "
            f"bemf on {100 * r['fraction_bemf_on']:5.0f} %  "
            f"pushes {100 * (r['fraction_pushes'] or 0):5.0f} %  "
            f"{r['hil_runs']:5d} runs {r['wall_s']:6.0f} s",
            file=sys.stderr,
            flush=True,
        )
        (out / "design_table.json").write_text(json.dumps({"push": args.push, "rows": rows}, indent=1) + "\n")
    for fam in ("given", "lambda", "walls"):
        fr = [r for r in rows if r["family"] == fam]
        if not fr:
            continue
        given = fam == "given"  # its own pushes per row: a column for them
        print(
            "\n| target |"
            + (" push |" if given else "")
            + " seeds landing: hil | pushes landing | the same seeds: lattice | confirmation seeds: reached "
            "| fresh seeds: hil | hil, back-EMF comp. on | most missed seeds: why (their walls) | runs | wall s |"
        )
        print("|---|" + ("---|" if given else "") + "---:|---:|---:|---:|---:|---:|---|---:|---:|")
        for r in fr:
            conf = "" if r["fraction_confirm"] is None else f"{100 * r['fraction_confirm']:.0f} %: "
            miss = "-"
            if r["missed"]:
                m = r["missed"][0]
                miss = f"{m['runs']}: {m['why']} ({', '.join(f'{w:g}' for w in m['walls']) or 'none'})"
            print(
                f"| {r['target']} |"
                + (f" {r['push']} |" if given else "")
                + f" {100 * r['fraction_seeds']:.0f} % | {100 * (r['fraction_pushes'] or 0):.0f} % | "
                f"{100 * r['fraction_cross']:.0f} % | {conf}{'yes' if r['reached'] else 'no'} | "
                f"{100 * r['fraction_fresh']:.0f} % | "
                f"{100 * r['fraction_bemf_on']:.0f} % | {miss} | {r['hil_runs']} | "
                f"{r['wall_s']:.0f} |"
            )
        ok = sum(r["fraction_seeds"] >= 0.9 for r in fr)
        print(f"\n{fam}: {ok} of {len(fr)} targets land in >= 90 % of the seeds")
        print(
            f"{fam}: {sum(r['reached'] for r in fr)} reported reached (>= 90 % of the verification's and the "
            "confirmation's seeds together)"
        )
    print(f"\ntotal wall time {time.perf_counter() - t_all:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
