"""Overlay a rig (or rehearsal) run and an emulator run of one scene: final angles per cell, emulator as lines, rig as
markers with the spread over repeats.

Both directories hold a summary.json (`python -m metacell_tools.experiment run|rehearse` and
`python -m host_emulator run`). Rig markers are the per-cell mean over repeats, error
bars span min..max of the repeats (a single repeat: no bar). The table gives, per cell,
both values and rig - emulator, and the pattern period of each run.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


class CompareError(ValueError):
    """A directory without a usable summary, or runs that cannot be compared."""


def load(d: Path) -> dict:
    d = Path(d)
    if d.exists() and not d.is_dir():
        raise CompareError(
            f"{d}: not a directory (give the output directory of `python -m metacell_tools.experiment run` or "
            "`python -m host_emulator run`, which holds summary.json; a logger's .npz is not a run)"
        )
    f = d / "summary.json"
    try:
        s = json.loads(f.read_text())
    except FileNotFoundError:
        raise CompareError(
            f"{f}: not found (run `python -m metacell_tools.experiment run` or `python -m host_emulator run` first)"
        ) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise CompareError(f"{f}: not valid JSON: {e}") from None
    except OSError as e:
        raise CompareError(f"{f}: cannot read it: {e.strerror or e}") from None
    if not isinstance(s, dict):
        raise CompareError(f"{f}: not a run summary")
    for k in ("scene", "final_alpha_rad", "final_beta_rad"):
        if k not in s:
            raise CompareError(f"{f}: no {k!r} key (not a run summary)")
    return s


def _arr(v) -> np.ndarray:
    return np.array([np.nan if x is None else float(x) for x in v], dtype=float)


def finals(s: dict, chain: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, low, high) per cell; low/high = min/max over repeats (= mean for one repeat or a simulation)."""
    m = _arr(s[f"final_{chain}_rad"])
    lo = _arr(s.get(f"final_{chain}_min_rad", s[f"final_{chain}_rad"]))
    hi = _arr(s.get(f"final_{chain}_max_rad", s[f"final_{chain}_rad"]))
    return m, lo, hi


def table(rig: dict, emu: dict) -> str:
    ra, ra_lo, ra_hi = finals(rig, "alpha")
    rb = finals(rig, "beta")[0]
    ea, eb = finals(emu, "alpha")[0], finals(emu, "beta")[0]
    lines = [
        f"scene {rig['scene']}: rig/rehearsal ({rig.get('model')}, {rig.get('repeats', 1)} repeat(s)) "
        f"vs emulator ({emu.get('model')})",
        " cell  alpha_rig  (min..max)        alpha_emu  d_alpha  |  beta_rig  beta_emu  d_beta",
    ]
    for j in range(len(ra)):

        def f(v, w=8):
            return f"{'n/a':>{w}}" if not math.isfinite(v) else f"{v:+{w}.3f}"

        lines.append(
            f" {j + 1:4d}  {f(ra[j], 9)}  ({f(ra_lo[j], 6)}..{f(ra_hi[j], 6)})  {f(ea[j], 9)}  "
            f"{f(ra[j] - ea[j])}  |  {f(rb[j])}  {f(eb[j])}  {f(rb[j] - eb[j])}"
        )
    da, db = ra - ea, rb - eb
    ok = np.isfinite(da)

    def rms(x):
        return float(np.sqrt(np.mean(x[np.isfinite(x)] ** 2))) if np.isfinite(x).any() else float("nan")

    lines.append(f" rms difference: alpha {rms(da):.3f} rad, beta {rms(db):.3f} rad over {int(ok.sum())} cell(s)")

    def p(s, k, unit):
        v = s.get(k)
        return "none" if v is None else f"{v:.3g} {unit}"

    lines.append(
        f" pattern period: rig {p(rig, 'pattern_period_cells', 'cells')}, emulator "
        f"{p(emu, 'pattern_period_cells', 'cells')}; oscillation period: rig "
        f"{p(rig, 'oscillation_period_s', 's')}, emulator {p(emu, 'oscillation_period_s', 's')}"
    )
    return "\n".join(lines)


def plot(rig: dict, emu: dict, path: Path) -> Path:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 6), constrained_layout=True)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, chain, colour in ((axes[0], "alpha", "C0"), (axes[1], "beta", "C1")):
        em = finals(emu, chain)[0]
        m, lo, hi = finals(rig, chain)
        j = np.arange(1, len(m) + 1)
        ax.plot(np.arange(1, len(em) + 1), em, "-", color=colour, lw=1.5, label=f"emulator ({emu.get('model')})")
        # min <= mean <= max up to rounding of the mean: clip the last-bit negatives matplotlib refuses
        yerr = np.clip(np.vstack([np.where(np.isfinite(lo), m - lo, 0), np.where(np.isfinite(hi), hi - m, 0)]), 0, None)
        ax.errorbar(
            j,
            m,
            yerr=yerr,
            fmt="o",
            color="k",
            mfc="white",
            ms=6,
            capsize=3,
            label=f"{'rig' if rig.get('model') == 'rig' else rig.get('model')}: mean, min..max over "
            f"{rig.get('repeats', 1)} repeat(s)",
        )
        ax.axhline(0, color="0.6", lw=0.8)
        ax.set_ylabel(f"{chain} at steady state (rad)")
        ax.legend(fontsize=8)
    axes[1].set_xlabel("cell j")
    axes[1].set_xticks(np.arange(1, len(finals(rig, "alpha")[0]) + 1))
    axes[0].set_title(
        f"{rig['scene']}: rig vs emulator (pattern period {rig.get('pattern_period_cells') or 0:.3g} vs "
        f"{emu.get('pattern_period_cells') or 0:.3g} cells)"
    )
    fig.savefig(path, dpi=110)
    return path


def compare(rig_dir: Path, emu_dir: Path, out: Path | None = None) -> tuple[str, Path]:
    rig, emu = load(rig_dir), load(emu_dir)
    if rig["scene"] != emu["scene"]:
        raise CompareError(f"different scenes: {rig_dir} ran {rig['scene']!r}, {emu_dir} ran {emu['scene']!r}")
    if len(rig["final_alpha_rad"]) != len(emu["final_alpha_rad"]):
        raise CompareError(f"different cell counts: {len(rig['final_alpha_rad'])} vs {len(emu['final_alpha_rad'])}")
    out = Path(out) if out else Path(rig_dir) / "compare.png"
    from host_emulator.outpaths import check_out_file

    problem = check_out_file(out, "--out")
    if problem:
        raise CompareError(problem)
    return table(rig, emu), plot(rig, emu, out)
