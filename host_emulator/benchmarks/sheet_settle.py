"""How long a sheet scene takes to settle: `python -m host_emulator.benchmarks.sheet_settle sheet_16x16 --t-end 40`.

Runs the scene to --t-end (default: twice its own t_end_s) and prints, over time, the largest change of any cell's
alpha within --window seconds and the largest distance from the final state; the settle time is the last time that
change exceeds --tol (rad). A state that holds still for a while and then moves again (a pattern that is a saddle,
left by a slow instability) shows as a plateau followed by growth: read the table, not only the last line. Slow
(a sheet of thousands of cells runs for minutes): a benchmark, never a test."""

from __future__ import annotations

import argparse
import sys

import numpy as np


def settle_time(t: np.ndarray, alpha: np.ndarray, window_s: float, tol: float) -> float | None:
    """The last sample time at which max_j |alpha_j(t) - alpha_j(t - window_s)| exceeds tol (t[0] when it never
    does; None when it still does at the end: the run has not settled)."""
    k = max(1, int(round(window_s / (t[1] - t[0])))) if len(t) > 1 else 1
    if len(t) <= k:
        return None
    change = np.abs(alpha[k:] - alpha[:-k]).max(axis=1)
    over = np.flatnonzero(change > tol)
    if not len(over):
        return float(t[0])
    if over[-1] == len(change) - 1:
        return None
    return float(t[k + over[-1]])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.sheet_settle", description=__doc__)
    ap.add_argument("scene", help="scene name or .toml path (a sheet, or any scene)")
    ap.add_argument("--t-end", type=float, default=None, help="simulated time, s (default: twice the scene's)")
    ap.add_argument("--window", type=float, default=0.1, help="change measured over this many seconds (0.1)")
    ap.add_argument("--tol", type=float, default=1e-6, help="settled: change within the window below this (1e-6 rad)")
    ap.add_argument("--every", type=float, default=1.0, help="table row every this many seconds (1)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override, as for run")
    args = ap.parse_args(argv)
    import host_emulator as he

    sc = he.load_scene(args.scene, args.set)
    t_end = args.t_end or 2 * sc.t_end_s
    r = he.run(sc, {"t_end_s": t_end})
    t, a = r.time, r.alpha
    print(f"{sc.name}: {sc.topology.describe()}, {sc.model}, {t_end:g} s simulated in {r.wall_s:.3g} s wall")
    k = max(1, int(round(args.window / (t[1] - t[0]))))
    print(f"{'t (s)':>8} {'max change in ' + format(args.window, 'g') + ' s':>22} {'max |alpha - final|':>20}")
    for tt in np.arange(args.every, t[-1] + 1e-9, args.every):
        i = min(int(np.searchsorted(t, tt - 1e-9)), len(t) - 1)
        ch = np.abs(a[i] - a[max(0, i - k)]).max()
        print(f"{t[i]:8.2f} {ch:22.3e} {np.abs(a[i] - a[-1]).max():20.3e}")
    st = settle_time(t, a, args.window, args.tol)
    print(
        f"settled (change < {args.tol:g} rad in {args.window:g} s) from t = {st:.2f} s"
        if st is not None
        else f"not settled by {t[-1]:g} s (change still > {args.tol:g} rad in {args.window:g} s)"
    )
    s = r.summary
    for key in ("pattern_kind", "dominant_wavelength_cells", "amplitude_rad"):
        if key in s:
            print(f"  {key}: {s[key]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
