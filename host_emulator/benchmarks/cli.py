"""`python -m host_emulator bench [--fidelity] [--quick]`: work-precision, ratios against scipy/py-pde, scaling,
fidelity cost."""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

from .common import fmt, pin_one_core

LATTICE_TARGET = 1e-4
LATTICE_RATIO_TARGET = 30.0


def _plot(panels, path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6 * len(panels), 4.6))
    axes = fig.subplots(1, len(panels), squeeze=False)
    for ax, (title, points, target) in zip(axes[0], panels):
        for meth in sorted({p.method for p in points}):
            pts = sorted((p.wall_s, p.error) for p in points if p.method == meth and p.error < 1e9)
            if not pts:
                continue
            style = "--" if meth.startswith(("scipy", "py-pde", "diffrax", "CVODE")) else "-"
            ax.loglog([w for w, _ in pts], [max(e, 1e-12) for _, e in pts], style, marker="o", ms=3, label=meth)
        if target:
            ax.axhline(target, color="k", lw=0.6, ls=":")
        ax.set_xlabel("CPU time per run (s, one pinned core)")
        ax.set_ylabel("max angle error (rad)")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def run_workprecision(args: argparse.Namespace, out: Path) -> int:
    from . import continuum as cb
    from . import scaling as sc
    from . import workprecision as wp

    t_start = time.perf_counter()
    from ..provenance import machine, provenance

    summary: dict[str, Any] = {"machine": machine(), "provenance": provenance()}  # written as JSON
    panels: list[tuple[str, list, float | None]] = []  # (title, points, target error) per figure panel
    status = 0

    print("== lattice: exp3_single_sigma9, 16 cells, sigma 9/125, push on alpha_8, 3 s simulated ==")
    scene, pts, ref_check = wp.lattice_workprecision(3.0, quick=args.quick)
    print(wp.points_table(pts))
    at, best, peer = wp.summarize(pts, LATTICE_TARGET)
    print(f"\n  time at max error {LATTICE_TARGET:g} rad (log-log interpolation on each method's Pareto front):")
    for m, w in at.items():
        print(f"    {m:18s} {fmt(None if w is None else w * 1e3)} ms")
    ratio = None
    if best and peer:
        ratio = peer[1] / best[1]
        print(
            f"  RATIO lattice: best scipy ({peer[0]}, {peer[1] * 1e3:.0f} ms) / best ours ({best[0]}, "
            f"{best[1] * 1e3:.2f} ms) = {ratio:.0f}x  (target >= {LATTICE_RATIO_TARGET:.0f}x: "
            f"{'met' if ratio >= LATTICE_RATIO_TARGET else 'NOT met'})"
        )
        status |= 0 if ratio >= LATTICE_RATIO_TARGET else 1
    peer_ratios: dict[str, tuple[str, float, float]] = {}  # family: (setting, wall, ratio to ours)
    for fam in ("diffrax", "CVODE", "scipy"):
        _, _, fb = wp.summarize(pts, LATTICE_TARGET, ours_prefix=(fam,))
        if best and fb:
            peer_ratios[fam] = (fb[0], fb[1], fb[1] / best[1])
    if best:
        print(
            f"  RATIOS lattice at {LATTICE_TARGET:g} rad, best of each peer / best ours ({best[0]}, "
            f"{best[1] * 1e3:.2f} ms): "
            + ", ".join(f"{f} {v[2]:.1f}x ({v[0]}, {v[1] * 1e3:.1f} ms)" for f, v in peer_ratios.items())
            + "".join(f"; {f}: not run" for f in ("diffrax", "CVODE", "scipy") if f not in peer_ratios)
        )
    summary["lattice_peer_ratios"] = peer_ratios
    front = wp.front_ratios(pts)
    print(
        "\n  lattice front: CPU time to reach each max angle error, the best of ours against the best method of each "
        "peer family (log-log on each method's Pareto front; medians of 5 runs for ours, diffrax and CVODE, all "
        "measured in this run)"
    )
    print("  " + wp.front_table(front).replace("\n", "\n  "))
    short = [r for r in front if r["ratio"] is not None and r["ratio"] < wp.FRONT_TARGET]
    unmeasured = [r for r in front if r["ratio"] is None]
    ratios = [r["ratio"] for r in front if r["ratio"] is not None]
    print(
        f"  FRONT lattice: best peer / best ours >= {wp.FRONT_TARGET:g}x at every error from "
        f"{max(wp.FRONT_TOLS):g} to {min(wp.FRONT_TOLS):g} rad: "
        + ("met" if not short and not unmeasured else "NOT met" if short else "not measured")
        + (f" (ratios {min(ratios):.1f}x-{max(ratios):.1f}x)" if ratios else "")
        + "".join(f"; {r['tol_rad']:g} rad: below target" for r in short)
        + "".join(f"; {r['tol_rad']:g} rad: ours or every peer never reach it" for r in unmeasured)
    )
    status |= 1 if short else 0
    summary["lattice_front_ratios"] = front
    summary["lattice"] = {
        "ratio": ratio,
        "best_ours": best,
        "best_scipy": peer,
        "reference_check_rad": ref_check,
        "points": [p.__dict__ for p in pts],
    }
    panels.append((f"lattice 16 cells, 3 s (ratio at {LATTICE_TARGET:g} rad: {fmt(ratio)}x)", pts, LATTICE_TARGET))

    if not args.no_hil:
        print("\n== hil: default scene (16 cells, firmware at 2 kHz), 3 s simulated ==")
        _, hpts = wp.hil_workprecision(3.0, quick=args.quick)
        print(wp.points_table(hpts))
        summary["hil"] = {"points": [p.__dict__ for p in hpts]}
        panels.append(("hil 16 cells, 3 s, vs rk4 x64 plant steps per tick", hpts, None))

    if not args.no_continuum:
        print(
            "\n== continuum: continuum_single (continuum PDE, docs/physics.md#linear-stability), "
            "16 cells x 4 points, 3 s simulated =="
        )
        _, cpts, have_pde = cb.continuum_workprecision(3.0, m=4, quick=args.quick)
        print(wp.points_table(cpts))
        if have_pde:
            peers = [p for p in cpts if p.method.startswith("py-pde")]
            tgt = max(LATTICE_TARGET, 1.01 * min(p.error for p in peers))
            at, best, peer = wp.summarize(cpts, tgt, ours_prefix=("py-pde",))
            cr = None
            if best and peer:
                cr = peer[1] / best[1]
                print(
                    f"  RATIO continuum at max error {tgt:.2g} rad: best py-pde ({peer[0]}, {peer[1]:.2f} s warm) / "
                    f"best ours ({best[0]}, {best[1] * 1e3:.1f} ms) = {fmt(cr)}x "
                    f"(target > 1x: {'met' if cr > 1 else 'NOT met'})"
                )
            else:  # no run of ours or of py-pde reaches the target
                print(f"  RATIO continuum at max error {tgt:.2g} rad: not measured (ours or py-pde never reach it)")
            summary["continuum"] = {"ratio": cr, "target_error": tgt, "best_ours": best, "best_pypde": peer}
        summary.setdefault("continuum", {})["points"] = [p.__dict__ for p in cpts]
        panels.append(("continuum 16x4 grid, 3 s", cpts, LATTICE_TARGET))

    if not args.no_scaling:
        print("\n== scaling: cost per cell-second, 16..4096 cells ==")
        cells_t, time_t, spreads = sc.scaling(quick=args.quick)
        print(cells_t)
        for m, (k, e10, e100) in spreads.items():
            print(
                f"  {m}: max/min cost per cell-second over 16..4096 cells: kernel {k:.2f}x, "
                f"run with 10 ms samples {e10:.2f}x, with 100 ms samples {e100:.2f}x (target <= 1.3x)"
            )
        print("\n== scaling: cost against simulated time (16 cells) ==")
        print(time_t)
        summary["scaling"] = {"spreads": spreads}

    out.mkdir(parents=True, exist_ok=True)
    png = out / "work_precision.png"
    _plot(panels, png)
    summary["machine"]["load_end"] = machine()["load"]
    (out / "bench.json").write_text(json.dumps(summary, indent=1, default=str) + "\n")
    print(f"\nwrote {png} and {out / 'bench.json'}; bench took {time.perf_counter() - t_start:.0f} s")
    return status


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator bench",
        description="Work-precision against scipy/py-pde, scaling, and (--fidelity) "
        "the cost and effect of each model component. Pinned to one core.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator bench --quick                # a smoke run\n"
        "  python -m host_emulator bench --out out/bench        # the full work-precision figures\n"
        "  python -m host_emulator bench --fidelity             # cost and effect of each model component",
    )
    ap.add_argument("--fidelity", action="store_true", help="only the fidelity-cost table")
    ap.add_argument("--quick", action="store_true", help="fewer step sizes/tolerances (a smoke run)")
    ap.add_argument("--no-hil", action="store_true", help="skip the hil (compiled firmware) work-precision")
    ap.add_argument("--no-continuum", action="store_true", help="skip the continuum model against py-pde")
    ap.add_argument("--no-scaling", action="store_true", help="skip the cost-against-cells scaling")
    ap.add_argument("--out", default="out/bench", help="directory for the PNG and JSON (default out/bench)")
    args = ap.parse_args(argv)
    from ..outpaths import check_out_dir

    problem = check_out_dir(args.out)
    if problem:
        print(f"bench: error: {problem}", file=sys.stderr)
        return 2
    where = pin_one_core()
    from ..provenance import machine_line

    print(f"# host_emulator bench on {where} [{platform.machine()}, python {platform.python_version()}]")
    print(f"# machine: {machine_line()}")
    from ..firmware import load

    load()  # compile outside every timing
    out = Path(args.out)
    if args.fidelity:
        from .fidelity import run_fidelity

        return run_fidelity(args, out)
    return run_workprecision(args, out)
