"""design.png: the verification runs' final profiles against the target, and the designed parameters."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .target import Target

if TYPE_CHECKING:
    from matplotlib.figure import FigureBase


def plot_design(doc: dict, target: Target, path: Path) -> FigureBase:
    """design.png: the verification runs' final profiles against the target, and the designed parameters (legends
    beside the axes, clear of every cell). Returns the Figure."""
    from matplotlib.figure import Figure

    n = target.cells
    cells = np.arange(1, n + 1)
    fig = Figure(figsize=(9.6, 6.2))
    ax, bx = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    runs = doc["verification"]["runs"]
    for r in runs:
        if "final_alpha_rad" in r:
            ax.plot(cells, r["final_alpha_rad"], color="C0" if r["landed"] else "C3", lw=0.7, alpha=0.6)
    amp = np.median([np.abs(r["final_alpha_rad"]).max() for r in runs if "final_alpha_rad" in r] or [0.6])
    mode = np.asarray(doc["linear_theory"]["mode_alpha"])
    ax.plot(cells, amp * mode, "k--", lw=1.2, label="linear theory: fastest mode (scaled)")
    for w in target.layout() if target.kind == "walls" else ():
        ax.axvline(w, color="k", lw=1.0)
    for c in target.rest:
        ax.axvspan(c - 0.5, c + 0.5, color="0.85", lw=0)
    v = doc["verification"]
    ax.plot([], [], color="C0", label="landed")
    ax.plot([], [], color="C3", label="missed")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_ylabel("final alpha (rad)")
    ax.set_title(
        f"target {target.text()}, push {doc['push_text']}: lands in {v['fraction_seeds'] * 100:.0f} % of "
        f"{v['seeds']} noise seeds, {100 * (v['fraction_pushes'] or 0):.0f} % of the pushes (hil)",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: never over a cell
    for k in doc["vary"]:
        vals = np.broadcast_to(np.asarray(doc["params"][k], dtype=float), (n,))
        bx.step(cells, vals, where="mid", label=k)
    for q in doc["pushes"]:
        bx.axvline(q["cell"], color="0.6", ls=":", lw=1)
    bx.set_xlabel("cell")
    bx.set_ylabel("N m/rad (alpha*: rad)")
    bx.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    bx.set_xticks(cells)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return fig
