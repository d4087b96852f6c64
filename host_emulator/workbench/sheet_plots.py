"""Pictures of a 2-D sheet: its field of alpha (or beta) drawn as an image (square lattice) or as hexagons (hexagonal
lattice), a row of snapshots at a few times (a sheet's answer to the chain's space-time map) and the final field.

Rows run down the picture (row 1 at the top, as the cell numbers read: cell = (row - 1) * cols + col), columns
left to right; a diverging colormap centred on 0 (CCW positive red, CW blue), one colour scale for every panel of a
figure. The inputs are what plots.py takes (a RunResult, a Dataset of the run layout, a run directory or a capture,
through inputs.as_run)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import FigureBase

    from ..scene import Scene
    from ..topology import Topology

CMAP = "RdBu_r"
SNAPSHOTS = 4  # panels of plot_snapshots by default


def _abs_max(x) -> float:
    x = np.abs(np.asarray(x, dtype=float))
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else 0.0


def hexagons(topology: Topology) -> np.ndarray:
    """(n, 6, 2) corners of each cell's hexagon around topology.positions() (pointy-top, touching its six
    neighbours: circumradius 1/sqrt(3) at unit spacing)."""
    r = 1.0 / math.sqrt(3.0)
    ang = np.deg2rad(90.0 + 60.0 * np.arange(6))
    corner = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    return topology.positions()[:, None, :] + corner[None, :, :]


def draw_field(ax: Axes, values: np.ndarray, topology: Topology, lim: float, *, cmap: str = CMAP) -> Any:
    """Draw one field (n,) (cell order) of a sheet into ax; returns the mappable (an AxesImage for a square sheet, a
    PolyCollection of hexagons for a hexagonal one) whose set_array/set_data redraws it."""
    v = np.asarray(values, dtype=float)
    lim = lim or 1.0
    if topology.kind == "hex":
        from matplotlib.collections import PolyCollection

        pc = PolyCollection(list(hexagons(topology)), array=v, cmap=cmap, edgecolors="none")
        pc.set_clim(-lim, lim)
        ax.add_collection(pc)
        xy = topology.positions()
        pad = 0.6
        ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
        ax.set_ylim(xy[:, 1].max() + pad, xy[:, 1].min() - pad)  # row 1 at the top
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        return pc
    im = ax.imshow(
        topology.grid(v),
        cmap=cmap,
        vmin=-lim,
        vmax=lim,
        origin="upper",
        extent=(0.5, topology.cols + 0.5, topology.rows + 0.5, 0.5),
        interpolation="nearest",
    )
    ax.set_xlabel("col")
    ax.set_ylabel("row")
    return im


def set_field(mappable: Any, values: np.ndarray, topology: Topology) -> None:
    """Redraw a mappable of draw_field with new values (n,)."""
    v = np.asarray(values, dtype=float)
    if topology.kind == "hex":
        mappable.set_array(v)
    else:
        mappable.set_data(topology.grid(v))


def snapshot_indices(t: np.ndarray, count: int = SNAPSHOTS) -> list[int]:
    """count sample indices spread evenly over the run after t = 0, the last sample included (t = 0 is the rest the
    push starts from); fewer when the run has fewer samples."""
    k = len(t)
    if k <= 1:
        return [0] * min(1, k)
    idx = np.unique(np.round(np.linspace(0, k - 1, count + 1)[1:]).astype(int))
    return [int(i) for i in idx]


def plot_snapshots(
    run: Any,
    *,
    times: Any = None,
    count: int = SNAPSHOTS,
    axes: Any = None,
    var: str = "alpha",
    scene: Scene | None = None,
    title: str = "",
) -> FigureBase:
    """A row of 2-D images of a sheet's alpha (var="beta": beta) at a few times: `times` (s; each the nearest
    sample), else `count` times spread over the run, the last included. One colour scale (max |alpha| over the
    panels), one colorbar. axes: the Axes to draw into (one per panel). Returns the Figure."""
    from .inputs import as_run
    from .plots import _title_of, new_figure

    view = as_run(run)
    topo = scene.topology if scene is not None else view.topology
    data = view.alpha if var == "alpha" else view.beta
    t = view.time
    if times is None:
        idx = snapshot_indices(t, count)
    else:
        idx = [int(np.argmin(np.abs(t - float(x)))) for x in np.ravel(times)]
    if not idx:
        raise ValueError("plot_snapshots: the run has no samples")
    if axes is None:
        w = 2.6 * len(idx) * max(0.6, min(1.6, topo.cols / topo.rows)) + 1.0
        fig: FigureBase = new_figure(figsize=(w, 3.4), constrained_layout=True)
        axes = list(np.ravel(fig.subplots(1, len(idx), squeeze=False)))
    else:
        axes = list(np.ravel(axes)) if isinstance(axes, (list, tuple, np.ndarray)) else [axes]
        fig = axes[0].figure
        if len(axes) < len(idx):
            raise ValueError(f"plot_snapshots: {len(idx)} snapshots, {len(axes)} axes")
    lim = _abs_max(data[idx]) or 1.0
    mappables = []
    for ax, k in zip(axes, idx, strict=False):
        mappables.append(draw_field(ax, data[k], topo, lim))
        ax.set_title(f"t = {t[k]:.3g} s", fontsize=9)
    m = mappables[0]
    fig.colorbar(m, ax=axes[: len(idx)], label=f"{var} (rad)", shrink=0.85)
    head = _title_of(view, scene, title) or f"{topo.describe()}: {var} snapshots"
    fig.suptitle(head, fontsize=9)
    return fig


def plot_final_field(run: Any, *, axes: Any = None, scene: Scene | None = None, title: str = "") -> FigureBase:
    """A sheet's final alpha and beta fields (each cell's last finite sample) side by side, each on its own
    diverging scale. Returns the Figure."""
    from .inputs import as_run
    from .plots import _title_of, new_figure

    view = as_run(run)
    topo = scene.topology if scene is not None else view.topology
    if axes is None:
        w = 2 * 3.2 * max(0.6, min(1.6, topo.cols / topo.rows)) + 1.2
        fig: FigureBase = new_figure(figsize=(w, 3.6), constrained_layout=True)
        axes = list(np.ravel(fig.subplots(1, 2, squeeze=False)))
    else:
        axes = list(np.ravel(axes)) if isinstance(axes, (list, tuple, np.ndarray)) else [axes]
        fig = axes[0].figure
    for ax, var in zip(axes, ("alpha", "beta"), strict=False):
        v = view.final(var)
        m = draw_field(ax, v, topo, _abs_max(v) or 1.0)
        fig.colorbar(m, ax=ax, label=f"{var} (rad)", shrink=0.85)
        ax.set_title(f"final {var}", fontsize=9)
    fig.suptitle(_title_of(view, scene, title) or f"{topo.describe()}: final pattern", fontsize=9)
    return fig
