"""A sheet sweep's figure: the phase diagram of pattern kinds (one fixed colour per analysis.pattern2d kind) over
one or two swept keys, the dominant wavelength beside it, and the linear theory's regime boundaries where the swept
keys are parameters. matplotlib, xarray and the linear theory (scipy) are imported when the figure is drawn."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plots import new_figure
from .errors import SweepError
from .figures import REGIME_MARKERS
from .schema import PATTERN_KINDS, _coord

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.figure import FigureBase

    from ...scene import Scene


KIND_COLOURS = {  # kind -> colour, fixed whatever the sweep holds (the legend lists every kind)
    "stripes": "#1f77b4",
    "spots": "#2ca02c",
    "labyrinth": "#9467bd",
    "rest": "#d9d9d9",
    "oscillation": "#d62728",
}
NO_KIND = "#555555"  # a failed or pending point (no kind)


def kind_grid(ds: xr.Dataset, xkey: str, ykey: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(kind index into PATTERN_KINDS, -1 where none; the dominant wavelength's median), shape (ny, nx) (ny = 1
    without ykey): the most frequent kind over the other swept keys and the seeds (ties: PATTERN_KINDS order)."""
    dims = ds["pattern_kind"].dims
    order = [ykey, xkey] if ykey is not None else [xkey]
    rest = [d for d in dims if d not in order]
    # loaded first: a string variable read lazily from sweep.nc cannot be transposed
    kinds = ds["pattern_kind"].load().transpose(*order, *rest).values.astype(str)
    lam = ds["dominant_wavelength_cells"].load().transpose(*order, *rest).values.astype(float)
    if ykey is None:
        kinds, lam = kinds[None], lam[None]
    ny, nx = kinds.shape[:2]
    kinds, lam = kinds.reshape(ny, nx, -1), lam.reshape(ny, nx, -1)
    code = np.full((ny, nx), -1)
    wave = np.full((ny, nx), np.nan)
    for i in range(ny):
        for j in range(nx):
            counts = [int((kinds[i, j] == k).sum()) for k in PATTERN_KINDS]
            if max(counts) > 0:
                code[i, j] = int(np.argmax(counts))
            if np.isfinite(lam[i, j]).any():
                wave[i, j] = float(np.nanmedian(lam[i, j]))
    return code, wave


def theory_regimes(ds: xr.Dataset, base: Scene, xkey: str, ykey: str | None = None) -> np.ndarray | None:
    """The linear theory's regime (analysis.sheet.unstable_q with the model's theory: the same for every lattice)
    at each cell of the (ny, nx) grid, the swept params.* keys applied to the base scene; None when neither swept
    key is a parameter (the theory does not change over the figure)."""
    from ...analysis.sheet import unstable_q
    from ...analysis.stability import theory_of

    fields = {f.name for f in dataclasses.fields(base.params)}

    def field(dim: str | None) -> str | None:
        key = str(ds[dim].attrs.get("key", dim)) if dim is not None else ""
        name = key.removeprefix("params.")
        return name if key.startswith("params.") and name in fields else None

    fx, fy = field(xkey), field(ykey)
    if fx is None and fy is None:
        return None
    xv = ds[xkey].values
    yv = ds[ykey].values if ykey is not None else [None]
    out = np.full((len(yv), len(xv)), "", dtype=object)
    for i, y in enumerate(yv):
        for j, x in enumerate(xv):
            change: dict[str, Any] = {k: getattr(v, "item", lambda v=v: v)() for k, v in ((fx, x), (fy, y)) if k}
            try:
                p = dataclasses.replace(base.params, **change)
                out[i, j] = unstable_q(p, theory_of(base.model, p, base.options.inertia))["regime"]
            except (TypeError, ValueError):  # a value the theory does not take: no regime drawn there
                out[i, j] = ""
    return out


def plot_pattern_kinds(ds: xr.Dataset, xkey: str, ykey: str | None = None, base: Scene | None = None) -> FigureBase:
    """The phase diagram of a sheet sweep: left, the pattern kind per cell of xkey x ykey (coordinate names or
    swept keys; ykey None: one row), a fixed colour per kind; right, the dominant wavelength (cells). With base
    (the sweep's base scene), the linear theory's regime boundaries as black lines on both panels and its regime
    per cell as a small marker. Returns the Figure."""
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    xkey = _coord(ds, xkey) or xkey
    ykey = (_coord(ds, ykey) or ykey) if ykey is not None else None
    for k in (xkey, ykey) if ykey is not None else (xkey,):
        if k not in ds.dims:
            raise SweepError(
                f"pattern kinds: {k!r} is not a swept key; swept: {', '.join(map(str, ds['status'].dims))}"
            )
    if "pattern_kind" not in ds:
        raise SweepError("pattern kinds: the dataset has no pattern_kind (a sweep stored before sheets had one)")
    code, wave = kind_grid(ds, xkey, ykey)
    regimes = theory_regimes(ds, base, xkey, ykey) if base is not None else None
    ny, nx = code.shape
    fig = new_figure(figsize=(11.5, 4.6 if ykey is not None else 2.6), constrained_layout=True)
    ax_k, ax_w = fig.subplots(1, 2)
    cmap = ListedColormap([KIND_COLOURS[k] for k in PATTERN_KINDS])
    shown = np.ma.masked_less(code, 0)
    ax_k.set_facecolor(NO_KIND)
    ax_k.imshow(shown, origin="lower", aspect="auto", cmap=cmap, vmin=-0.5, vmax=len(PATTERN_KINDS) - 0.5)
    ax_w.set_facecolor("white")
    im = ax_w.imshow(np.ma.masked_invalid(wave), origin="lower", aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=ax_w, label="dominant wavelength (cells)")
    xv = np.asarray(ds[xkey].values)
    yv = np.asarray(ds[ykey].values) if ykey is not None else np.array([""])
    handles: list = [Patch(color=KIND_COLOURS[k], label=k) for k in PATTERN_KINDS]
    handles.append(Patch(color=NO_KIND, label="failed / pending"))
    for ax in (ax_k, ax_w):
        ax.set_xticks(range(nx), [f"{v:.4g}" if np.issubdtype(xv.dtype, np.number) else str(v) for v in xv])
        ax.tick_params(axis="x", labelrotation=90, labelsize=7)
        ax.set_yticks(range(ny), [f"{v:.4g}" if np.issubdtype(yv.dtype, np.number) else str(v) for v in yv])
        ax.tick_params(axis="y", labelsize=7)
        ax.set_xlabel(str(ds[xkey].attrs.get("key", xkey)))
        if ykey is not None:
            ax.set_ylabel(str(ds[ykey].attrs.get("key", ykey)))
        if regimes is not None:
            _boundaries(ax, regimes)
    if regimes is not None:
        for r, mk in REGIME_MARKERS.items():
            ii, jj = np.nonzero(regimes == r)
            if len(ii):
                ax_k.plot(jj + 0.3, ii - 0.3, mk, ms=3, color="k", mfc="none", lw=0)
                handles.append(Line2D([], [], marker=mk, color="k", mfc="none", lw=0, ms=4, label=f"theory: {r}"))
        handles.append(Line2D([], [], color="k", lw=1.5, label="theory: regime boundary"))
    fig.legend(handles=handles, fontsize=7, loc="outside right upper")
    scene = ds.attrs.get("scene", "")
    ax_k.set_title(f"pattern kind (most frequent over seeds): {scene}", fontsize=9)
    ax_w.set_title("dominant wavelength (median over seeds; blank: none)", fontsize=9)
    return ax_k.figure


def _boundaries(ax, regimes: np.ndarray) -> None:
    """Black lines along the cell edges where the theory's regime changes between neighbouring cells."""
    ny, nx = regimes.shape
    for i in range(ny):
        for j in range(nx):
            if j + 1 < nx and regimes[i, j] != regimes[i, j + 1]:
                ax.plot([j + 0.5, j + 0.5], [i - 0.5, i + 0.5], color="k", lw=1.5)
            if i + 1 < ny and regimes[i, j] != regimes[i + 1, j]:
                ax.plot([j - 0.5, j + 0.5], [i + 0.5, i + 0.5], color="k", lw=1.5)
