"""Overlay two runs of one scene, rig or emulated: final angles per cell, the second run as lines, the first as
markers with the spread over its repeats.

Either path is anything ``host_emulator.load`` opens: an experiment directory (`python -m metacell_tools.experiment
run|rehearse`), an emulator run directory (`python -m host_emulator run`), a logger capture (NPZ/CSV) or a
python-can log (ASC, BLF, ...). A directory with a summary.json gives the per-cell mean of its repeats' final
angles, with min..max over the repeats; a capture gives each cell's last sample. Each run is named by its source
(rig, rehearsal:<model>, emulator:<model>, or unknown for a file that does not say). The table gives, per cell,
both values and their difference, and the pattern period of each run.

Runs with time series (anything but a summary alone) are also aligned on the push (align.py): each run's clock
shifted to the onset of its pushed cell's motion, the table gives both onsets and the rms difference of alpha after
it, and OUT_time.png (beside the overlay) draws every cell's alpha against the time since the push.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host_emulator.analysis.observables import spatial_period
from host_emulator.workbench.datasets import LoadError, _summary_source, final_profile, load
from metacell_common.outpaths import check_out_file

from . import align


class CompareError(ValueError):
    """A path without a usable run, or runs that cannot be compared."""


@dataclass
class Run:
    """The final profile of one run: per-cell mean and min..max over its repeats (alpha and beta, rad)."""

    path: Path
    source: str
    scene: str  # "" when the data does not say
    repeats: int
    finals: dict  # chain -> (mean, lo, hi), each (N,)
    pattern_period_cells: float | None
    oscillation_period_s: float | None
    what: str  # how the final profile was taken
    data: object = None  # its time series (the dataset host_emulator.load gives), None for a summary alone
    push: tuple[int, str] | None = None  # (cell, chain) of its scene's first push, when it says

    @property
    def cells(self) -> int:
        return len(self.finals["alpha"][0])


def _arr(v) -> np.ndarray:
    return np.array([np.nan if x is None else float(x) for x in v], dtype=float)


def _from_summary(d: Path, s: dict, source: str | None) -> Run:
    for k in ("scene", "final_alpha_rad", "final_beta_rad"):
        if k not in s:
            raise CompareError(f"{d / 'summary.json'}: no {k!r} key (not a run summary)")
    finals = {}
    for chain in ("alpha", "beta"):
        m = _arr(s[f"final_{chain}_rad"])
        finals[chain] = (
            m,
            _arr(s.get(f"final_{chain}_min_rad", s[f"final_{chain}_rad"])),
            _arr(s.get(f"final_{chain}_max_rad", s[f"final_{chain}_rad"])),
        )
    reps = int(s.get("repeats", 1))
    try:  # the time series beside the summary (trajectories.npz, the run's own files), if any
        data = load(d, source=source)
    except Exception:  # noqa: BLE001 - a summary alone still has its final angles
        data = None
    return Run(
        d,
        source or _summary_source(s),
        str(s["scene"]),
        reps,
        finals,
        s.get("pattern_period_cells"),
        s.get("oscillation_period_s"),
        f"mean of {reps} repeat(s), bars min..max" if reps > 1 else "final sample",
        data,
        align.scene_push(s, getattr(data, "attrs", None)),
    )


def open_run(path: Path, source: str | None = None) -> Run:
    """The final profile of whatever host_emulator.load opens at path."""
    path = Path(path)
    f = path / "summary.json"
    if path.is_dir() and f.exists():
        try:
            s = json.loads(f.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise CompareError(f"{f}: not valid JSON: {e}") from None
        except OSError as e:
            raise CompareError(f"{f}: cannot read it: {e.strerror or e}") from None
        if not isinstance(s, dict):
            raise CompareError(f"{f}: not a run summary")
        return _from_summary(path, s, source)
    if not path.exists() and not any(path.with_suffix(x).exists() for x in (".npz", ".csv")):
        raise CompareError(
            f"{path}: not found (run `python -m metacell_tools.experiment run` or `python -m host_emulator run` first)"
        )
    try:
        ds = load(path, source=source)
    except (LoadError, OSError) as e:
        raise CompareError(str(e)) from None
    finals = {c: (final_profile(ds, c),) * 3 for c in ("alpha", "beta")}
    a = finals["alpha"][0]
    period = spatial_period(a) if np.isfinite(a).all() and np.ptp(a) > 0.03 else None
    return Run(
        path,
        str(ds.attrs.get("source", "unknown")),
        str(ds.attrs.get("scene", "")),
        1,
        finals,
        period,
        None,
        "each cell's last sample",
        ds,
        align.scene_push(None, dict(ds.attrs)),
    )


def table(a: Run, b: Run) -> str:
    ra, ra_lo, ra_hi = a.finals["alpha"]
    rb = a.finals["beta"][0]
    ea, eb = b.finals["alpha"][0], b.finals["beta"][0]
    scene = a.scene or b.scene or "unknown scene"
    lines = [
        f"scene {scene}: A = {a.source} ({a.what}, {a.path}) vs B = {b.source} ({b.what}, {b.path})",
        " cell   alpha_A  (min..max)           alpha_B  A-B      |   beta_A    beta_B   A-B",
    ]

    def f(v, w=8):
        return f"{'n/a':>{w}}" if not math.isfinite(v) else f"{v:+{w}.3f}"

    for j in range(len(ra)):
        lines.append(
            f" {j + 1:4d}  {f(ra[j], 8)}  ({f(ra_lo[j], 7)}..{f(ra_hi[j], 7)})  {f(ea[j], 8)}  "
            f"{f(ra[j] - ea[j])}  |  {f(rb[j])}  {f(eb[j])}  {f(rb[j] - eb[j])}"
        )
    da, db = ra - ea, rb - eb
    ok = np.isfinite(da)

    def rms(x):
        return float(np.sqrt(np.mean(x[np.isfinite(x)] ** 2))) if np.isfinite(x).any() else float("nan")

    lines.append(f" rms difference: alpha {rms(da):.3f} rad, beta {rms(db):.3f} rad over {int(ok.sum())} cell(s)")

    def p(v, unit):
        return "none" if v is None else f"{v:.3g} {unit}"

    lines.append(
        f" pattern period: A {p(a.pattern_period_cells, 'cells')}, B {p(b.pattern_period_cells, 'cells')}; "
        f"oscillation period: A {p(a.oscillation_period_s, 's')}, B {p(b.oscillation_period_s, 's')}"
    )
    lines.append(" (A: markers; B: lines. Angles in rad; n/a: a cell without data.)")
    return "\n".join(lines)


def plot(a: Run, b: Run, path: Path) -> Path:
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    fig = Figure(figsize=(7.5, 6), constrained_layout=True)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, chain, colour in ((axes[0], "alpha", "C0"), (axes[1], "beta", "C1")):
        em = b.finals[chain][0]
        m, lo, hi = a.finals[chain]
        j = np.arange(1, len(m) + 1)
        ax.plot(np.arange(1, len(em) + 1), em, "-", color=colour, lw=1.5, label=f"B: {b.source}, {b.what}")
        # min <= mean <= max up to rounding of the mean: clip the last-bit negatives matplotlib refuses
        yerr = np.clip(np.vstack([np.where(np.isfinite(lo), m - lo, 0), np.where(np.isfinite(hi), hi - m, 0)]), 0, None)
        ax.errorbar(
            j,
            m,
            yerr=yerr if a.repeats > 1 else None,
            fmt="o",
            color="k",
            mfc="white",
            ms=6,
            capsize=3,
            label=f"A: {a.source}, {a.what}",
        )
        ax.axhline(0, color="0.6", lw=0.8)
        ax.set_ylabel(f"{chain} at the end (rad)")
        ax.legend(fontsize=8)
    axes[1].set_xlabel("cell j")
    axes[1].xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[1].set_xticks(np.arange(1, a.cells + 1))
    axes[0].set_title(
        f"{a.scene or b.scene or 'unknown scene'}: {a.source} (A) vs {b.source} (B)\n"
        f"pattern period {a.pattern_period_cells or 0:.3g} vs {b.pattern_period_cells or 0:.3g} cells",
        fontsize=10,
    )
    fig.savefig(path, dpi=110)
    return path


def compare(
    a_path: Path, b_path: Path, out: Path | None = None, sources: tuple[str | None, str | None] = (None, None)
) -> tuple[str, Path]:
    a, b = open_run(a_path, sources[0]), open_run(b_path, sources[1])
    if a.scene and b.scene and a.scene != b.scene:
        raise CompareError(f"different scenes: {a_path} ran {a.scene!r}, {b_path} ran {b.scene!r}")
    if a.cells != b.cells:
        raise CompareError(f"different cell counts: {a.cells} vs {b.cells}")
    out = Path(out) if out else (Path(a_path) if Path(a_path).is_dir() else Path(a_path).parent) / "compare.png"
    problem = check_out_file(out, "--out")  # before the plot is drawn: one line, never a traceback
    if problem:
        raise CompareError(problem)
    return table(a, b) + "\n" + "\n".join(in_time(a, b, out)), plot(a, b, out)


def in_time(a: Run, b: Run, out: Path) -> list[str]:
    """The alignment of the two runs' time series on the push (align.py): table lines, and OUT_time.png beside the
    overlay when both runs hold the push."""
    runs = (("A", a), ("B", b))
    missing = [f"{x} ({r.path}) has no time series (a summary alone)" for x, r in runs if r.data is None]
    if missing:
        return align.lines(None, None, "; ".join(missing))
    push = a.push or b.push  # one scene: a capture (no scene of its own) takes the other run's push
    ta, tb = align.make_track(a.data, push), align.make_track(b.data, push)
    text = align.lines(ta, tb)
    png = align.plot(
        ta, tb, out.with_name(f"{out.stem}_time{out.suffix}"), (a.source, b.source), a.scene or b.scene or "unknown"
    )
    if png is not None:
        text.append(f" time series aligned on the push: {png}")
    return text
