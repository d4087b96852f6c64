"""Can per-cell parameters pick a sheet's stripe orientation? A striped per-cell sigma prepattern along the rows
or the columns of a 16 x 16 sheet against the uniform law, each over draws of the rig's uncertainty (hil).

    python -m host_emulator.benchmarks.sheet_orientation --seeds 10

Prints one row per prepattern: the pattern kinds, the median dominant wavelength, the mean orientation, and how many
runs ended as stripes within 15 degrees of the prepattern's own orientation (docs/design.md, "Sheets")."""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from ..analysis import pattern2d
from ..workbench.batch import run_batch
from ..workbench.design.sheet_driver import sheet_base
from ..workbench.design.sheet_runs import sheet_scene
from ..workbench.design.sheet_target import SheetPush

WITHIN_DEG = 15.0


def prepattern(base_params, axis: str, period: float, hi: float, lo: float):
    """sigma hi on the stripes where cos(2 pi (x - 1/2) / period) > 0 of the row (axis "rows") or column index,
    lo elsewhere; "none": the base law everywhere."""
    if axis == "none":
        return base_params
    top = base_params.topology
    x = np.array([top.row_col(j + 1)[0 if axis == "rows" else 1] for j in range(top.n)])
    sig = tuple(hi if np.cos(2 * np.pi * (v - 0.5) / period) > 0 else lo for v in x)
    return dataclasses.replace(base_params, sigma=sig)


def _axial_mean(degs: list[float]) -> float | None:
    """The mean of orientations in [0, 180) as axes (179 and 1 average to 0): half the doubled angles' mean."""
    if not degs:
        return None
    d = np.radians(2 * np.asarray(degs))
    return float(np.degrees(np.arctan2(np.sin(d).mean(), np.cos(d).mean())) / 2 % 180)


def run(seeds: int, period: float, hi: float, lo: float, size: int = 16) -> list[dict]:
    base = sheet_base("default", (size, size))
    top = base.params.topology
    c = (size + 1) // 2
    rows = []
    # the stripes' wavevector along the prepattern's varying index: rows vary -> k along y (90 deg), cols -> 0 deg
    for axis, want in (("none", None), ("rows", 90.0), ("cols", 0.0)):
        p = prepattern(base.params, axis, period, hi, lo)
        scenes = [sheet_scene(base, p, (SheetPush(c, c, 1),), 0.02, 0.1, 2000 + s) for s in range(seeds)]
        ms = [pattern2d.measures(r.t, r.alpha, top) for r in run_batch(scenes)]
        kinds = {k: sum(m["pattern_kind"] == k for m in ms) for k in pattern2d.KINDS}
        degs = [m["orientation_deg"] for m in ms if m["orientation_deg"] is not None]
        hit = (
            sum(
                m["pattern_kind"] == "stripes"
                and min(abs(m["orientation_deg"] - want) % 180, 180 - abs(m["orientation_deg"] - want) % 180)
                <= WITHIN_DEG
                for m in ms
            )
            if want is not None
            else None
        )
        lams = [m["dominant_wavelength_cells"] for m in ms if m["dominant_wavelength_cells"]]
        rows.append(
            {
                "prepattern": axis,
                "kinds": {k: v for k, v in kinds.items() if v},
                "median_wavelength": float(np.median(lams)) if lams else None,
                "mean_orientation": _axial_mean(degs),
                "oriented": hit,
                "seeds": seeds,
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.sheet_orientation", description=__doc__)
    ap.add_argument("--seeds", type=int, default=10, help="draws of the rig's uncertainty per prepattern (default 10)")
    ap.add_argument("--period", type=float, default=8.0, help="the prepattern's period in cells (default 8)")
    ap.add_argument("--hi", type=float, default=0.09, help="sigma on the prepattern's high stripes (default 0.09)")
    ap.add_argument("--lo", type=float, default=0.03, help="sigma on its low stripes (default 0.03)")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = run(a.seeds, a.period, a.hi, a.lo)
    print(f"16 x 16 sheet, hil, push at the centre, sigma prepattern {a.hi:g} / {a.lo:g} of period {a.period:g} cells")
    print(
        "| prepattern | kinds | median wavelength (cells) | mean orientation (deg, as axes) | stripes within 15 deg |"
    )
    print("|---|---|---:|---:|---:|")
    for r in rows:
        kinds = ", ".join(f"{k} {v}" for k, v in r["kinds"].items())
        lam = f"{r['median_wavelength']:.1f}" if r["median_wavelength"] else "-"
        deg = f"{r['mean_orientation']:.0f}" if r["mean_orientation"] is not None else "-"
        ok = "-" if r["oriented"] is None else f"{r['oriented']} of {r['seeds']}"
        print(f"| {r['prepattern']} | {kinds} | {lam} | {deg} | {ok} |")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
