"""A sweep's figures: the phase diagram (every point against sigma, with the linear theory's bands) and the regime
map (the most frequent outcome over two swept keys). matplotlib, xarray and the linear theory (scipy) are imported
when a figure is drawn."""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING

import numpy as np

from ..plots import new_figure
from .errors import SweepError
from .schema import OUTCOMES, _coord

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.axes import Axes
    from matplotlib.figure import FigureBase

    from ...scene import Scene


OUTCOME_STYLE = {  # outcome -> (marker, colour, label) in the phase diagram
    "pattern": ("o", "k", "pattern: selected wavelength 2(N-1)/Z"),
    "rest": ("v", "0.45", "rest (drawn at the bottom)"),
    "oscillation": ("^", "C3", "oscillation (drawn at the top)"),
    "moving": ("s", "C1", "still moving at the end (drawn at the top)"),
    "failed": ("x", "C3", "failed (drawn at the bottom)"),
}


def theory_bands_over(base: Scene, sigmas: np.ndarray) -> dict:
    """The linear theory of the base scene's model at each sigma: {'stationary': [(lo, hi), ...] per sigma,
    'oscillatory': ..., 'fastest': the fastest stationary wavelength, 'regime': ...}, hi inf for an interval reaching
    the longest waves."""
    import dataclasses

    from ...analysis.stability import dispersion, theory_of

    out: dict = {"stationary": [], "oscillatory": [], "fastest": [], "regime": []}
    for sg in sigmas:
        p = dataclasses.replace(base.params, sigma=float(sg))
        d = dispersion(p, theory=theory_of(base.model, p, base.options.inertia), n_cells=base.cells, n_kappa=600)
        for kind in ("stationary", "oscillatory"):
            out[kind].append(
                [
                    (iv["lambda_cells"][0], iv["lambda_cells"][1] or math.inf)
                    for iv in d["unstable_intervals"]
                    if iv["kind"] == kind
                ]
            )
        stat = [iv for iv in d["unstable_intervals"] if iv["kind"] == "stationary"]
        best = max(stat, key=lambda iv: iv["fastest_growth_per_s"]) if stat else None
        out["fastest"].append((best and best["fastest_lambda_cells"]) or np.nan)
        out["regime"].append(d["regime"])
    return out


def plot_phase_diagram(
    ds: xr.Dataset, base: Scene | None = None, *, ax: Axes | None = None, color_by: str | None = None
) -> FigureBase:
    """Every point of the sweep against sigma, drawn by outcome: the selected wavelength (2(N-1)/Z, cells) of a
    pattern, rest at the bottom edge, an oscillation or a still-moving run at the top edge, failures as crosses;
    with a second swept key (color_by: its coordinate name; default the first swept key besides sigma and seed)
    the points are coloured by its value. Beside them the linear theory of the base scene's model at each sigma:
    every unstable interval (stationary shaded blue, oscillatory hatched red; an interval reaching lambda -> inf
    is drawn up to the top edge) and the fastest wavelength. Returns the Figure."""
    sname = _coord(ds, "params.sigma")
    if sname is None:
        raise SweepError("phase diagram: params.sigma is not swept")
    if ax is None:
        fig = new_figure(figsize=(10, 5), constrained_layout=True)
        ax = fig.add_subplot(111)
    n = int(np.max(np.ravel(ds.attrs.get("cells", 16))))  # a sheet's [rows, cols]: its longer side
    ylo, yhi = 1.5, 4.0 * n
    others = [str(d) for d in ds["status"].dims if d not in (sname, "seed")]
    cby = color_by if color_by is not None else (others[0] if others else None)
    if cby is not None and cby not in others:
        raise SweepError(f"phase diagram: color_by={cby!r} is not a swept key; swept: {', '.join(others) or 'none'}")
    order = [sname] + ([cby] if cby else []) + [d for d in ds["status"].dims if d not in (sname, cby)]
    sig = np.asarray(ds[sname].values, dtype=float)
    lam = ds["pattern_wavelength_cells"].transpose(*order).values
    outc = ds["outcome"].transpose(*order).values.astype(str) if "outcome" in ds else None
    cvals = list(ds[cby].values) if cby else [None]
    lam = lam.reshape(len(sig), len(cvals), -1)
    outc = outc.reshape(lam.shape) if outc is not None else np.where(np.isfinite(lam), "pattern", "moving")
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    spread = 0.004 * (sig.max() - sig.min() or 1.0)  # colours side by side, not on top of each other
    for ci in range(len(cvals)):
        dx = (ci - (len(cvals) - 1) / 2) * spread if len(cvals) > 1 else 0.0
        for oc, (mk, col, label) in OUTCOME_STYLE.items():
            m = outc[:, ci, :] == oc
            if not m.any():
                continue
            xs = np.repeat(sig, m.shape[1]).reshape(m.shape)[m] + dx
            if oc == "pattern":
                ys = lam[:, ci, :][m]
            elif oc in ("rest", "failed"):
                ys = np.full(xs.shape, ylo * 1.08)
            else:
                ys = np.full(xs.shape, yhi / 1.12)
            colour = col if cby is None or oc in ("failed",) else cmap(ci / max(1, len(cvals) - 1))
            lab = label if ci == 0 else None
            ax.plot(xs, ys, mk, ms=4, alpha=0.7, color=colour, mfc=colour if oc == "pattern" else "none", label=lab)
    if cby:
        from matplotlib.lines import Line2D

        handles = [
            Line2D(
                [],
                [],
                marker="o",
                ls="",
                color=cmap(ci / max(1, len(cvals) - 1)),
                label=f"{cby} = {cv:g}" if isinstance(cv, (float, int, np.number)) else f"{cby} = {cv}",
            )
            for ci, cv in enumerate(cvals)
        ]
        leg2 = ax.legend(
            handles=handles, fontsize=7, loc="lower left", bbox_to_anchor=(1.01, 0.0), title="colour", title_fontsize=7
        )
        ax.add_artist(leg2)
    if base is not None:
        sg = np.linspace(sig.min(), sig.max(), max(80, len(sig)))
        th = theory_bands_over(base, sg)
        for kind, colour, hatch in (("stationary", "C0", None), ("oscillatory", "C3", "//")):
            slots = max([0] + [len(x) for x in th[kind]])
            for k in range(slots):
                lo = np.array([x[k][0] if len(x) > k else np.nan for x in th[kind]])
                hi = np.array([min(x[k][1], yhi) if len(x) > k else np.nan for x in th[kind]])
                ax.fill_between(
                    sg,
                    lo,
                    hi,
                    color=colour,
                    alpha=0.15,
                    hatch=hatch,
                    lw=0,
                    label=f"linear theory: {kind} unstable" if k == 0 else None,
                )
        ax.plot(sg, th["fastest"], color="C0", lw=1.2, label="linear theory: fastest stationary wavelength")
        from ...analysis.stability import theory_of

        tname = theory_of(base.model, base.params, base.options.inertia).label()
    else:
        tname = ""
    ax.set_ylim(ylo, yhi)
    ax.set_yscale("log")
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullFormatter

    ax.yaxis.set_major_locator(FixedLocator([t for t in (2, 3, 5, 7.5, 10, 15, 20, 30, 60) if t < yhi]))
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("sigma (N·m/rad)")
    ax.set_ylabel("wavelength (cells)")
    nseed = ds.sizes.get("seed", 1)
    pooled = [d for d in ds["status"].dims if d not in (sname, cby)]
    ax.set_title(
        f"phase diagram: {ds.attrs.get('scene', '')}, {int(np.prod([ds.sizes[d] for d in pooled])) if pooled else 1} "
        f"point(s) per marker column{f' ({nseed} seeds)' if 'seed' in pooled else ''}"
        + (f"\ntheory: {tname}" if tname else ""),
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: it never hides a point
    return ax.figure


def outcome(ds: xr.Dataset) -> np.ndarray:
    """Per point: the index in OUTCOMES (rest, pattern, oscillation, moving, failed); -1 pending."""
    if "outcome" in ds:
        oc = ds["outcome"].values.astype(str)
    else:  # an older dataset
        rest = ds["at_rest"].values == 1
        osc = np.isfinite(ds["oscillation_period_s"].values)
        steady = ds["steady"].values == 1
        oc = np.where(rest, "rest", np.where(osc, "oscillation", np.where(steady, "pattern", "moving")))
        st = ds["status"].values.astype(str)
        oc = np.where(st == "failed", "failed", oc)
    code = np.full(oc.shape, -1)
    for i, name in enumerate(OUTCOMES):
        code[oc == name] = i
    code[ds["status"].values.astype(str) == "pending"] = -1
    return code


REGIME_MARKERS = {
    "rest": ".",
    "stationary_pattern": "o",
    "broadband_pattern": "s",
    "uniform_oscillation": "^",
    "pattern_and_oscillation": "D",
}


def plot_regime_map(ds: xr.Dataset, xkey: str, ykey: str | None = None, *, ax: Axes | None = None) -> FigureBase:
    """The most frequent outcome (rest / pattern / oscillation / moving / failed) over the other swept keys, on xkey
    x ykey (coordinate names, or the swept keys), and on each cell a marker for the regime the linear theory of
    the model that ran gives there (first point of the pooled ones). ykey None: one row over xkey (a one-parameter
    sweep: the seeds pooled, never an axis). Returns the Figure."""
    from matplotlib.colors import ListedColormap

    xkey = _coord(ds, xkey) or xkey
    ykey = (_coord(ds, ykey) or ykey) if ykey is not None else None
    for k in (xkey, ykey) if ykey is not None else (xkey,):
        if k not in ds.dims:
            raise SweepError(f"regime map: {k!r} is not a swept key; swept: {', '.join(map(str, ds['status'].dims))}")
    if ax is None:
        fig = new_figure(figsize=(7.5, 4.8), constrained_layout=True)
        ax = fig.add_subplot(111)
    import xarray as xr

    dims = ds["status"].dims
    code = xr.DataArray(outcome(ds), dims=dims)
    code = code.transpose(ykey, xkey, ...) if ykey is not None else code.transpose(xkey, ...).expand_dims("row")
    c = code.values.reshape(code.shape[0], code.shape[1], -1)
    mode = np.full(c.shape[:2], -1)
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            v = c[i, j][c[i, j] >= 0]
            if len(v):
                mode[i, j] = np.bincount(v, minlength=len(OUTCOMES)).argmax()
    colours = ["0.85", "C0", "C3", "C1", "k"]
    cmap = ListedColormap(colours)
    xv = np.asarray(ds[xkey].values)
    yv = np.asarray(ds[ykey].values) if ykey is not None else np.array(["all"])
    ax.imshow(
        np.ma.masked_less(mode, 0),
        origin="lower",
        aspect="auto",
        cmap=cmap,
        vmin=-0.5,
        vmax=len(OUTCOMES) - 0.5,
        interpolation="nearest",
    )
    from matplotlib.artist import Artist
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Artist] = [Patch(color=cmap(i), label=f"run: {o}") for i, o in enumerate(OUTCOMES)]
    if "regime" in ds:
        rg = ds["regime"]
        rg = rg.transpose(ykey, xkey, ...) if ykey is not None else rg.transpose(xkey, ...).expand_dims("row")
        reg = rg.values.astype(str).reshape(len(yv), len(xv), -1)[:, :, 0]
        for name, mk in REGIME_MARKERS.items():
            yy, xx = np.nonzero(reg == name)
            if len(xx):
                ax.plot(xx, yy, mk, ms=4, color="w", mec="k", mew=0.6, ls="")
                handles.append(Line2D([], [], marker=mk, ls="", color="w", mec="k", label=f"theory: {name}"))
    ax.set_xticks(range(len(xv)))
    ax.set_xticklabels(
        [f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v) for v in xv],
        rotation=90 if len(xv) > 8 else 0,
        fontsize=7,
    )
    ax.set_yticks(range(len(yv)))
    ax.set_yticklabels([f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v) for v in yv], fontsize=7)
    if len(xv) > 16:
        for lab in ax.get_xticklabels()[1::2]:
            lab.set_visible(False)
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel(ds[xkey].attrs.get("key", xkey))
    if ykey is not None:
        ax.set_ylabel(ds[ykey].attrs.get("key", ykey))
    else:
        ax.set_yticks([0], [f"all {ds.sizes.get('seed', 1)} seed(s)" if "seed" in ds.dims else "all"])
    ax.set_title(f"regime map (most frequent outcome): {ds.attrs.get('scene', '')}", fontsize=10)
    return ax.figure


def _save(fig, path):
    fig.savefig(path, dpi=110)
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close(fig)
