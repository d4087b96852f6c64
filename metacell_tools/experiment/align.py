"""Two runs' time series aligned on the push: each run's own clock shifted so that 0 is when its pushed cell first
moved, then overlaid cell by cell and compared (rms over the time both cover after the push).

A run's time origin depends on where it came from (an emulator run: the scene's start; an experiment: the drive's
enable; a capture: its first sample, wherever in the scene the logger began), so the final angles alone are all
two runs share. The push is the one event both hold: its onset is the first sample at which the pushed cell's
chain is MOVE_COUNTS encoder counts from its first sample (the scene's first perturbation names the cell; without a
scene, the first cell to move). A capture that began after the push has no onset (it opened on a moving or settled
lattice): `python -m host_emulator serve --wait-client` starts the scene when the logger opens the port.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from metacell_tools.rigtools.logger import RAD_PER_COUNT

from .summary import MOVE_COUNTS

MOVE_RAD = MOVE_COUNTS * RAD_PER_COUNT


@dataclass
class Track:
    """One run's time series (its own clock, s) and the onset of its push on that clock (None: none found)."""

    t: np.ndarray  # (T,)
    alpha: np.ndarray  # (T, N) rad, NaN where a cell has no sample
    beta: np.ndarray
    push_s: float | None
    pushed: str  # "alpha_8", or why there is no onset


def scene_push(summary: dict | None, attrs: dict | None = None) -> tuple[int, str] | None:
    """(cell, chain) of the scene's first perturbation, from a run summary's "perturbation" list or a dataset's
    perturbation.K.* attributes; None if neither names one."""
    ps = list((summary or {}).get("perturbation") or [])
    if not ps and attrs:
        k = 1
        while f"perturbation.{k}.cell" in attrs:
            ps.append({f: attrs.get(f"perturbation.{k}.{f}") for f in ("cell", "chain", "start_s")})
            k += 1
    ps = [p for p in ps if isinstance(p, dict) and p.get("cell") is not None]
    if not ps:
        return None
    p = min(ps, key=lambda p: float(p.get("start_s") or 0.0))
    return int(p["cell"]), str(p.get("chain") or "alpha")


def onset(t: np.ndarray, x: np.ndarray) -> float | None:
    """First time at which x (one cell's angle, NaN: no sample) is MOVE_RAD from its first sample; None if never."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return None
    t, x = t[ok], x[ok]
    moved = np.nonzero(np.abs(x - x[0]) >= MOVE_RAD - 1e-12)[0]
    return float(t[moved[0]]) if moved.size else None


def make_track(ds, push: tuple[int, str] | None) -> Track:
    """The Track of a dataset (host_emulator.load), its onset found for the pushed (cell, chain) or, without one,
    for whichever cell moves first."""
    t = np.asarray(ds["time"].values, dtype=float)
    a, b = (np.asarray(ds[c].values, dtype=float) for c in ("alpha", "beta"))
    if push is not None:
        cell, chain = push
        if not 1 <= cell <= a.shape[1]:
            return Track(t, a, b, None, f"no cell {cell} in the data")
        s = onset(t, (a if chain == "alpha" else b)[:, cell - 1])
        name = f"{chain}_{cell}"
        return Track(t, a, b, s, name if s is not None else f"{name} never moved {MOVE_COUNTS} counts")
    best: tuple[float, str] | None = None
    for chain, x in (("alpha", a), ("beta", b)):
        for j in range(x.shape[1]):
            s = onset(t, x[:, j])
            if s is not None and (best is None or s < best[0]):
                best = (s, f"{chain}_{j + 1}")
    if best is None:
        return Track(t, a, b, None, f"no cell moved {MOVE_COUNTS} counts")
    return Track(t, a, b, best[0], best[1])


def aligned(a: Track, b: Track) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(tau, alpha_A, alpha_B) on A's samples from the push to the end of the shorter run after it (B interpolated
    onto A's times, per cell); None without both onsets or without overlap."""
    if a.push_s is None or b.push_s is None:
        return None
    ta, tb = a.t - a.push_s, b.t - b.push_s
    end = min(ta[-1], tb[-1])
    keep = (ta >= 0) & (ta <= end)
    if keep.sum() < 2:
        return None
    tau = ta[keep]
    n = min(a.alpha.shape[1], b.alpha.shape[1])
    xb = np.full((tau.size, n), np.nan)
    for j in range(n):
        ok = np.isfinite(b.alpha[:, j])
        if ok.sum() >= 2:
            xb[:, j] = np.interp(tau, tb[ok], b.alpha[ok, j], left=np.nan, right=np.nan)
    return tau, a.alpha[keep, :n], xb


def lines(a: Track | None, b: Track | None, why: str = "") -> list[str]:
    """The table's lines about the alignment."""
    if a is None or b is None:
        return [f" not aligned in time: {why}"]
    out = []
    if a.push_s is None or b.push_s is None:
        miss = " and ".join(f"{x}: {t.pushed}" for x, t in (("A", a), ("B", b)) if t.push_s is None)
        return [
            f" not aligned in time: no push in the data ({miss}); a capture that began after the push cannot be "
            "aligned (python -m host_emulator serve --wait-client starts the scene with the capture)"
        ]
    out.append(
        f" aligned on the push ({a.pushed} moved {MOVE_COUNTS} counts): A at {a.push_s:.4f} s, B at {b.push_s:.4f} s "
        "of their own clocks"
    )
    al = aligned(a, b)
    if al is None:
        out.append(" (no time after the push in both runs)")
        return out
    tau, xa, xb = al
    d = xa - xb
    ok = np.isfinite(d)
    rms = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    out.append(
        f" after the push (0..{tau[-1]:.2f} s): alpha differs by {rms:.3f} rad rms, "
        f"{float(np.nanmax(np.abs(d))) if ok.any() else float('nan'):.3f} rad at most"
    )
    return out


def plot(a: Track, b: Track, path: Path, labels: tuple[str, str], title: str) -> Path | None:
    """Each cell's alpha against the time since the push: B as a line, A as dots; None without both onsets."""
    if a.push_s is None or b.push_s is None:
        return None
    from matplotlib.figure import Figure

    n = min(a.alpha.shape[1], b.alpha.shape[1])
    cols = 4
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(10, 1.8 * rows + 0.8), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, sharey=True)).ravel()
    for j in range(n):
        ax = axes[j]
        ax.plot(b.t - b.push_s, b.alpha[:, j], "-", color="C0", lw=1.2, label=f"B: {labels[1]}")
        ax.plot(a.t - a.push_s, a.alpha[:, j], ".", color="k", ms=2, label=f"A: {labels[0]}")
        ax.axvline(0, color="0.6", lw=0.8)
        ax.set_title(f"cell {j + 1}", fontsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax in axes[(rows - 1) * cols : n]:
        ax.set_xlabel("t - push (s)")
    axes[0].set_ylabel("alpha (rad)")
    axes[0].legend(fontsize=7)
    fig.suptitle(
        f"{title}: aligned on the push of {a.pushed} (A at {a.push_s:.3f} s, B at {b.push_s:.3f} s)", fontsize=10
    )
    fig.savefig(path, dpi=90)
    return path
