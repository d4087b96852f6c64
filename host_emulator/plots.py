"""PNG plots of a run: space-time maps of alpha and beta, the final pattern, the dispersion curve."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_spacetime(t, alpha, beta, path, title=""):
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    n = alpha.shape[1]
    for ax, data, lab in ((axes[0], alpha, "alpha"), (axes[1], beta, "beta")):
        lim = float(np.abs(data).max()) or 1.0
        im = ax.imshow(data.T, aspect="auto", origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim,
                       extent=(t[0], t[-1], 0.5, n + 0.5), interpolation="nearest")
        ax.set_ylabel("cell j")
        fig.colorbar(im, ax=ax, label=f"{lab} (rad)")
    axes[1].set_xlabel("t (s)")
    axes[0].set_title(title or "space-time")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_final(alpha, beta, path, title=""):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
    j = np.arange(1, len(alpha) + 1)
    ax.plot(j, alpha, "o-", label="alpha")
    ax.plot(j, beta, "s--", label="beta")
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("cell j")
    ax.set_ylabel("angle (rad)")
    ax.set_xticks(j)
    ax.legend()
    ax.set_title(title or "final pattern")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_dispersion_png(params, path, *, inertia=False):
    """Uses analysis.stability.plot_dispersion; returns False (no file) if that module is unavailable."""
    try:
        from .analysis.stability import plot_dispersion
    except ImportError:
        return False
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    plot_dispersion(params, ax=ax, inertia=inertia)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def plot_run(res, scene, outdir: Path, *, inertia=False) -> list[Path]:
    outdir = Path(outdir)
    files = [outdir / "spacetime.png", outdir / "final_pattern.png"]
    plot_spacetime(res.t, res.alpha, res.beta, files[0], f"{scene.name} ({scene.model})")
    plot_final(res.alpha[-1], res.beta[-1], files[1], f"{scene.name}: t = {res.t[-1]:.2f} s")
    d = outdir / "dispersion.png"
    if plot_dispersion_png(scene.params, d, inertia=inertia):
        files.append(d)
    return files
