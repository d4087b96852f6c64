"""Plots of a run: space-time maps of alpha and beta (with a growth-phase panel), the final pattern, the dispersion;
a 2-D sheet's snapshots and final field instead of the chain's space-time map and profile (sheet_plots.py).

Every function takes ``ax=`` (or ``axes=``) to draw into the caller's axes and returns the matplotlib Figure.
Without axes, a figure comes from pyplot when the caller already uses pyplot (a notebook: the figure shows
inline), else a bare ``matplotlib.figure.Figure`` (no backend, no global state). The package never calls
``matplotlib.use``: the user's backend is left alone.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, FigureBase

    from ..analysis.stability import Theory
    from ..params import Params
    from ..scene import Scene


def new_figure(figsize: tuple[float, float] = (8, 6), **kw: Any) -> Figure:
    """A Figure: through pyplot if the caller imported it (inline display in notebooks), else a bare Figure."""
    if "matplotlib.pyplot" in sys.modules:
        return sys.modules["matplotlib.pyplot"].figure(figsize=figsize, **kw)
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, **kw)


def cell_ticks(axis: Any, n: int) -> None:
    """Integer cell ticks on a matplotlib Axis (every cell up to 16, else 1 and every 4th): cells are 1..n, never
    2.5 or 7.5 (what an automatic locator puts on an image extent of 0.5..n + 0.5)."""
    from matplotlib.ticker import FixedLocator, NullLocator

    axis.set_major_locator(FixedLocator(list(range(1, n + 1)) if n <= 16 else [1, *range(4, n + 1, 4)]))
    axis.set_minor_locator(NullLocator())


def _save(fig, path):
    fig.savefig(path, dpi=110)
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close(fig)


def _arrays(run, alpha=None, beta=None):
    """(t, alpha, beta, view): arrays given as such, or any input inputs.as_run reads (view None for arrays)."""
    if alpha is not None:
        return np.asarray(run, dtype=float), np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float), None
    from .inputs import as_run

    v = as_run(run)
    return v.time, v.alpha, v.beta, v


def _abs_max(x) -> float:
    """max |x| over the finite samples (0.0 when there are none: a capture's cell that never sent one)."""
    x = np.abs(np.asarray(x, dtype=float))
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else 0.0


def _growth_end(t, alpha, frac=0.9):
    """Time at which max_j |alpha_j| first reaches `frac` of its final-window level (the pattern has formed)."""
    amp = np.abs(np.nan_to_num(alpha, nan=0.0)).max(axis=1)
    level = np.median(amp[int(0.9 * len(amp)) :]) if len(amp) > 10 else amp[-1]
    if not level > 0:
        return None
    k = np.flatnonzero(amp >= frac * level)
    return float(t[k[0]]) if len(k) else None


def _title_attrs(attrs: dict, title: str = "") -> str:
    """A title from a dataset's attributes (a run loaded back, a capture): name (source), sigma and the pushes."""
    name = title or str(attrs.get("scene") or "") or Path(str(attrs.get("origin") or "")).name
    src = str(attrs.get("source") or "")
    head = name + (f" ({src})" if src and not title and src not in name else "")
    sig = attrs.get("params.sigma")
    pushes, k = [], 1
    while f"perturbation.{k}.cell" in attrs or f"perturbation.{k}.row" in attrs:
        q = {f: attrs.get(f"perturbation.{k}.{f}") for f in ("chain", "cell", "row", "col", "torque_Nm", "duration_s")}
        where = q["cell"] if q["cell"] is not None else f"({q['row']},{q['col']})"
        try:
            tq = float(q["torque_Nm"]) * 1e3  # type: ignore[arg-type]  # a bad value: TypeError, caught
            pushes.append(f"{tq:+.0f} mN·m on {q['chain']}_{where} for {q['duration_s']} s")
        except (TypeError, ValueError):
            pass
        k += 1
    if sig is None:
        return head
    sv = np.ravel(np.asarray(sig, dtype=float))
    sig_text = f"sigma per cell {sv.min():.4g}..{sv.max():.4g}" if sv.size > 1 else f"sigma = {sv[0]:.4g}"
    return head + f"\n{sig_text} N·m/rad; push: {', '.join(pushes) or 'no push'}"


def _title_of(view, scene=None, title=""):
    if scene is not None and hasattr(scene, "params"):
        return _title(scene, title)
    if view is not None and view.scene is not None:
        return _title(view.scene, title)
    if view is not None and view.attrs:
        return _title_attrs(view.attrs, title)
    return title


def _title(scene=None, title=""):
    if scene is None or not hasattr(scene, "params"):
        return title
    p = scene.params
    push = (
        ", ".join(
            f"{q.torque_Nm * 1e3:+.0f} mN·m on {q.chain}_{_where(q)} for {q.duration_s:g} s"
            for q in getattr(scene, "perturbations", ())
        )
        or "no push"
    )
    if "sigma" in p.varying_keys:
        sv = p.per_cell("sigma")
        sig = f"sigma per cell {sv.min():.4g}..{sv.max():.4g}"
    else:
        sig = f"sigma = {p.per_cell('sigma')[0]:.4g}"
    other = [k for k in p.varying_keys if k != "sigma"]
    return (title or scene.name) + f"\n{sig} N·m/rad{'; per cell: ' + ', '.join(other) if other else ''}; push: {push}"


def _where(q) -> str:
    """A push's place as the scene named it: 8, or (8,8) on a sheet."""
    return f"({q.row},{q.col})" if getattr(q, "row", 0) else str(q.cell)


def _sheet(view, scene) -> bool:
    """True when the run is a 2-D sheet (its scene's or its dataset's topology says so)."""
    if scene is not None and hasattr(scene, "topology"):
        return bool(scene.topology.is_sheet)
    return view is not None and view.topology.is_sheet


def plot_spacetime(
    run: Any,
    alpha: np.ndarray | None = None,
    beta: np.ndarray | None = None,
    *,
    ax: Axes | None = None,
    axes: Any = None,  # 2 Axes (alpha, beta), or 4 with the growth panel, in any nesting
    scene: Scene | None = None,
    title: str = "",
    growth_panel: bool = True,
) -> FigureBase:
    """Space-time maps of alpha and beta (cells x time); with growth_panel, a second column zooms on the
    growth phase (until the pattern reaches 90 % of its final amplitude, at least 0.5 s).

    run: a RunResult (api or controller), an xarray Dataset of the run layout (r.to_xarray(), he.load(...)), a run
    directory or a capture path (anything he.load opens), or t with alpha=, beta= arrays (T, N). ax/axes: one Axes
    (alpha only) or a sequence of 2 (alpha, beta) or 4 (alpha, beta, alpha zoom, beta zoom). Returns the Figure.
    A 2-D sheet has no space-time map: its snapshots (sheet_plots.plot_snapshots) are drawn instead."""
    t, a, b, view = _arrays(run, alpha, beta)
    if alpha is None and _sheet(view, scene):
        from .sheet_plots import plot_snapshots

        return plot_snapshots(view, axes=axes if axes is not None else ax, scene=scene, title=title)
    if axes is None and ax is not None:
        axes = [ax] if not isinstance(ax, (list, tuple, np.ndarray)) else list(np.ravel(ax))
    if axes is None:
        ncol = 2 if growth_panel else 1
        fig: FigureBase = new_figure(figsize=(8 + 3 * (ncol - 1), 6), constrained_layout=True)
        grid = fig.subplots(2, ncol, squeeze=False, gridspec_kw={"width_ratios": [2.2, 1] if ncol == 2 else [1]})
        axes = [grid[0, 0], grid[1, 0]] + ([grid[0, 1], grid[1, 1]] if ncol == 2 else [])
    else:
        axes = list(np.ravel(axes))
        fig = axes[0].figure
    n = a.shape[1]
    t_zoom = None
    if len(axes) >= 4:
        te = _growth_end(t, a)
        t_zoom = min(t[-1], max(0.5, 1.2 * te if te else 0.5))
    panels = [(axes[0], a, "alpha", None)]
    if len(axes) >= 2:
        panels.append((axes[1], b, "beta", None))
    if t_zoom is not None:
        panels += [(axes[2], a, "alpha", t_zoom), (axes[3], b, "beta", t_zoom)]
    for axi, data, lab, tz in panels:
        sel = slice(None) if tz is None else slice(0, int(np.searchsorted(t, tz, side="right")))
        d, tt = data[sel], t[sel]
        lim = _abs_max(data) or 1.0
        im = axi.imshow(
            d.T,
            aspect="auto",
            origin="lower",
            cmap="RdBu_r",
            vmin=-lim,
            vmax=lim,
            extent=(tt[0], tt[-1] if len(tt) > 1 else tt[0] + 1e-9, 0.5, n + 0.5),
            interpolation="nearest",
        )
        axi.set_ylabel("cell j")
        cell_ticks(axi.yaxis, n)
        axi.set_xlabel("t (s)")
        if tz is None:
            fig.colorbar(im, ax=axi, label=f"{lab} (rad)")
        else:
            axi.set_title(f"{lab}: growth phase, 0-{tz:.2g} s", fontsize=9)
    axes[0].set_title(_title_of(view, scene, title) or "space-time", fontsize=9)
    return fig


def plot_final(
    run: Any,
    alpha: np.ndarray | None = None,
    beta: np.ndarray | None = None,
    *,
    ax: Axes | None = None,
    scene: Scene | None = None,
    title: str = "",
) -> FigureBase:
    """Final alpha and beta profile against cell index (each cell's last sample). run: a RunResult, an xarray
    Dataset of the run layout, a run directory or a capture path, or final alpha with beta= (N,). A 2-D sheet: its
    final alpha and beta fields (sheet_plots.plot_final_field)."""
    view = None
    if alpha is None:
        from .inputs import as_run

        view = as_run(run)
        if _sheet(view, scene):
            from .sheet_plots import plot_final_field

            return plot_final_field(view, axes=ax, scene=scene, title=title)
        a, b = view.final("alpha"), view.final("beta")
    else:
        a, b = np.asarray(run, dtype=float), np.asarray(alpha, dtype=float)  # plot_final(alpha, beta)
    if ax is None:
        new: Figure = new_figure(figsize=(7, 3.8), constrained_layout=True)
        ax = new.add_subplot(111)
    fig = ax.figure
    j = np.arange(1, len(a) + 1)
    ax.plot(j, a, "o-", label="alpha")
    ax.plot(j, b, "s--", label="beta")
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("cell j")
    ax.set_ylabel("angle (rad)")
    cell_ticks(ax.xaxis, len(j))
    ax.legend()
    ax.set_title(_title_of(view, scene, title) or "final pattern", fontsize=9)
    return fig


def plot_dispersion(
    params: Any,
    *,
    ax: Axes | None = None,
    inertia: bool = False,
    measured_period_s: float | None = None,
    theory: Theory | None = None,
) -> FigureBase:
    """Growth rate against wavelength (analysis.stability.plot_dispersion) of the given theory (theory_of(model,
    params, inertia); default the lattice with or without inertia); the measured period, if given, is marked as a
    horizontal line at its angular frequency 2 pi / T. Returns the Figure.

    params: a Params, or a run (a RunResult, a Dataset of the run layout, a run directory): its parameters, and its
    model's theory unless theory= is given (a capture carries no parameters: ValueError)."""
    from ..analysis.stability import plot_dispersion as _pd
    from ..params import Params

    if not isinstance(params, Params):
        from .inputs import as_run

        view = as_run(params)
        params = view.params
        if params is None:
            raise ValueError(f"plot_dispersion: {view.name or 'this run'} carries no parameters (a capture?)")
        theory = theory if theory is not None else view.theory()
        params = params.uniform() if params.heterogeneous else params

    if ax is None:
        fig = new_figure(figsize=(7, 4.2), constrained_layout=True)
        ax = fig.add_subplot(111)
    _pd(params, ax=ax, inertia=inertia, theory=theory)
    if measured_period_s:
        w = 2 * np.pi / measured_period_s
        lo, hi = ax.get_ylim()
        if w <= hi:
            ax.axhline(w, color="C3", lw=0.8, ls="-.", label=f"measured 2π/T, T = {measured_period_s:.3g} s")
            ax.legend(fontsize=7, loc="lower right")
    return ax.figure


def plot_chain_modes(params: Params, *, theory: Theory | None = None, count: int = 6) -> FigureBase:
    """The linear theory of a chain whose cells differ (analysis.chain): growth rate of every mode against its
    cosine wavelength 2n/m, and the alpha shape of the fastest modes. Returns the Figure."""
    from ..analysis.chain import chain_modes

    res = chain_modes(params, theory)
    fig = new_figure(figsize=(7, 6), constrained_layout=True)
    ax, bx = fig.subplots(2, 1)
    modes = res["modes"]
    for kind, color in (("stationary", "C0"), ("oscillatory", "C3")):
        ms = [m for m in modes if m["kind"] == kind]
        ax.plot(
            [m["dct_lambda_cells"] or 4 * params.cells for m in ms],
            [m["growth_per_s"] for m in ms],
            "o",
            ms=4,
            color=color,
            label=f"{kind} modes",
        )
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xscale("log")
    ax.set_xlabel("mode's cosine wavelength 2n/m (cells; uniform mode at 4n)")
    ax.set_ylabel("growth rate Re s (1/s)")
    ax.set_title(
        "linear theory: " + (theory.label() if theory else "lattice with inertia") + ", per-cell law", fontsize=9
    )
    ax.legend(fontsize=7)
    cells = np.arange(1, params.cells + 1)
    for k, m in enumerate(modes[:count]):
        if m["growth_per_s"] <= 0 and k > 0:
            break
        bx.plot(cells, m["alpha"], marker="o", ms=3, label=f"s = {m['growth_per_s']:.3g}/s, walls {m['domain_walls']}")
    bx.axhline(0, color="k", lw=0.5)
    bx.set_xlabel("cell")
    bx.set_ylabel("alpha of the mode")
    bx.legend(fontsize=7)
    return fig


def plot_dispersion_png(
    params: Params,
    path: str | Path,
    *,
    inertia: bool = False,
    measured_period_s: float | None = None,
    theory: Theory | None = None,
    column: bool = False,
) -> bool:
    """Write the dispersion plot to path, in the format its suffix names (a chain whose cells differ: its modes,
    plot_chain_modes); False (no file) if the analysis module is unavailable. column: one paper column wide."""
    try:
        if params.heterogeneous:
            fig = plot_chain_modes(params, theory=theory)
        else:
            fig = plot_dispersion(params.uniform(), inertia=inertia, measured_period_s=measured_period_s, theory=theory)
    except ImportError:
        return False
    if column:
        _column(fig, 2.6 if not params.heterogeneous else 4.2)
    _save(fig, path)
    return True


FORMATS = ("png", "pdf", "svg")  # what --format writes (matplotlib picks the writer by the suffix)
COLUMN_WIDTH_IN = 3.4  # one column of a two-column paper (86 mm)


def _column(fig, height_in: float) -> None:
    """Resize a figure to one paper column, with fonts to match (titles 7 pt, the rest 6 pt)."""
    fig.set_size_inches(COLUMN_WIDTH_IN, height_in)
    for ax in fig.axes:
        ax.title.set_fontsize(6.5)
        for item in (ax.xaxis.label, ax.yaxis.label, *ax.get_xticklabels(), *ax.get_yticklabels()):
            item.set_fontsize(6)
        leg = ax.get_legend()
        if leg is not None:
            for tx in leg.get_texts():
                tx.set_fontsize(5.5)


def plot_run(
    res: Any,
    scene: Scene | None,
    outdir: Path,
    *,
    source: str | None = None,
    name: str | None = None,
    fmt: str = "png",
    column: bool = False,
) -> list[Path]:
    """The run's figures in outdir: spacetime (a 2-D sheet: snapshots), final_pattern and dispersion, as fmt (png,
    pdf or svg). Returns the paths.

    res: a controller RunResult (t, alpha, beta) with its scene, or anything inputs.as_run reads (scene None: the
    run's own, or the attributes of a loaded run or capture; a capture has no dispersion). source labels the data in
    the titles ("emulator:<model>" by default, "rehearsal:<model>", "rig"); name replaces the scene's name in them;
    the dispersion is the linear theory of the scene's model. column: sized for one paper column (3.4 in wide,
    without the growth-phase panel)."""
    from .inputs import as_run

    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: expected one of {', '.join(FORMATS)}")
    outdir = Path(outdir)
    view = as_run(res)
    scene = scene if scene is not None else view.scene
    label = source or (f"emulator:{scene.model}" if scene is not None else view.source)
    name = name or (scene.name if scene is not None else view.name)
    first = "snapshots" if _sheet(view, scene) else "spacetime"
    files = [outdir / f"{first}.{fmt}", outdir / f"final_pattern.{fmt}"]
    fig = plot_spacetime(view, scene=scene, title=f"{name} ({label})", growth_panel=not column)
    if column:
        _column(fig, 3.6)
    _save(fig, files[0])
    fin = plot_final(view, scene=scene, title=f"{name} ({label}): t = {view.time[-1]:.2f} s")
    if column:
        _column(fin, 2.5)
    _save(fin, files[1])
    d = outdir / f"dispersion.{fmt}"
    params = scene.params if scene is not None else view.params
    theory = view.theory() if scene is None else None
    if scene is not None:
        from ..analysis.summary import theory_for

        theory = theory_for(scene)
    if params is not None and plot_dispersion_png(params, d, theory=theory, column=column):
        files.append(d)
    return files
