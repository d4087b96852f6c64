"""Python API for notebooks and scripts: ``host_emulator.run(scene, overrides=..., accuracy=...)``.

Example::

    import host_emulator as he
    r = he.run("default", overrides={"params.sigma": 0.05, "t_end_s": 2.0})
    r.summary["pattern_wavelength_cells"]
    ds = r.to_xarray()            # dims (time, cell), units and every scene parameter as attributes
    he.plot_spacetime(r)          # a matplotlib Figure; pass ax= to draw into your own axes

Nothing here selects a matplotlib backend: figures show inline in Jupyter and in whatever backend the user set.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..analysis.summary import SHEET_KEYS
from ..provenance import provenance
from ..scene import apply_overrides, scene_from_dict, scene_table
from ..scene import list_scenes as _ls
from ..scene import load_scene as _load
from .plots import plot_spacetime

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.axes import Axes
    from matplotlib.figure import FigureBase

    from ..analysis.stability import Theory
    from ..scene import Scene
    from .trackers import Tracker

__all__ = ["RunResult", "run", "load_scene", "list_scenes"]


# {"params.sigma": 0.05, ...} or ["params.sigma=0.05", ...] (the keys of `run --set`), one "KEY=VALUE", or None
Overrides = Mapping[str, object] | Sequence[str] | str | None


def override_list(overrides: Overrides) -> list[str]:
    """["KEY=VALUE", ...] from a dict, a list or one string. A dict's string values are read as on the command line
    (`run --set`): "6/125" is a fraction, "firmware" a word, "true" a boolean; numbers and booleans as they are."""
    if overrides is None:
        return []
    if isinstance(overrides, Mapping):
        return [f"{k}={_text(v)}" for k, v in overrides.items()]
    if isinstance(overrides, str):
        return [overrides]
    return [str(o) for o in overrides]


def _text(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return repr(float(v))


@dataclass
class RunResult:
    """One run of a scene.

    time: (T,) s, sample times 0, dt_out, ..., t_end.
    alpha, beta: (T, N) rad, angle of the tall (honey) and the short cylinder of cells j = 1..N (CCW positive).
    summary: the dict that ``python -m host_emulator run`` writes as summary.json (observables, dispersion,
    solver info, parameters, provenance).
    scene: the validated Scene the run used. wall_s: wall-clock seconds of the run.
    """

    scene: Scene
    time: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    summary: dict
    wall_s: float
    info: dict = field(default_factory=dict)

    def __getattr__(self, name: str):
        if name == "t":
            raise AttributeError("RunResult has no 't': the sample times are r.time (the dataset's 'time' dimension)")
        raise AttributeError(f"'RunResult' object has no attribute {name!r}")

    @property
    def theory(self) -> Theory:
        """The linear theory of the model that ran (analysis.stability.theory_of: inertia as the scene, the hil
        motors' back-EMF damping): pass it to he.plot_dispersion(r.scene.params, theory=r.theory)."""
        from ..analysis.summary import theory_for

        return theory_for(self.scene)

    @property
    def source(self) -> str:
        """What produced the data: 'emulator:<model>'."""
        return str(self.summary.get("source") or f"emulator:{self.scene.model}")

    def to_xarray(self) -> xr.Dataset:
        """The run in the one dataset layout of every run, rig or emulated (host_emulator.workbench.datasets):
        alpha, beta (time x cell, rad; a sheet's time x row x col, row and col 1-based, cell the 2-D coordinate of
        the cell numbers) and, for the lattice and continuum models, the commanded reaction torques; coords time
        (s), cell (1..N); attributes: source, units, every scene parameter (params.*, model_options.*,
        perturbation.*), the scalar observables, the linear theory and provenance."""
        from .datasets import from_run

        return from_run(self.scene, self.time, self.alpha, self.beta, self.summary)

    def plot(self, ax: Axes | None = None) -> FigureBase:
        """Space-time map of alpha and beta (a Figure; see plots.plot_spacetime), or a sheet's snapshots of alpha
        (plots.plot_snapshots)."""
        if self.scene.topology.is_sheet:
            from .sheet_plots import plot_snapshots

            return plot_snapshots(self, axes=ax)
        return plot_spacetime(self, ax=ax)


def _flat(prefix, v, out):
    if isinstance(v, dict):
        for k, x in v.items():
            _flat(f"{prefix}.{k}" if prefix else str(k), x, out)
    elif isinstance(v, (list, tuple)):
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) and v:
            out[prefix] = np.asarray(v, dtype=float)
        else:
            for i, x in enumerate(v):
                _flat(f"{prefix}.{i + 1}", x, out)
    elif v is None:
        out[prefix] = "none"
    elif isinstance(v, bool):
        out[prefix] = int(v)
    elif isinstance(v, (int, float, str, np.integer, np.floating)):
        out[prefix] = v
    else:
        out[prefix] = str(v)


# the summary's observables a dataset carries as attributes observable.<key> (he.run's to_xarray and a run directory
# loaded back alike), when the summary has them: the chain's, and a sheet's 2-D measures (analysis.pattern2d)
OBSERVABLE_KEYS = (
    "steady",
    "at_rest",
    "domain_walls",
    "domain_wall_bonds",
    "pattern_wavelength_cells",
    "dominant_mode",
    "pattern_period_cells",
    "oscillation_period_s",
    "amplitude_rad",
    "growth_rate_per_s",
    *SHEET_KEYS,
)


def observable_attrs(summary: dict, out: dict) -> None:
    """The summary's OBSERVABLE_KEYS into out as flat observable.<key> attributes."""
    for k in OBSERVABLE_KEYS:
        if k in summary:
            _flat(f"observable.{k}", summary[k], out)


def netcdf_attrs(scene: Scene, summary: dict | None = None) -> dict:
    """Flat NetCDF-safe attributes: the scene (every parameter), scalar observables, provenance; and, for any lattice
    but the open chain, topology.cells / topology.lattice / topology.boundary (Topology.as_dict())."""
    out: dict = {}
    d = scene.as_dict()
    topo = scene.topology
    _flat(
        "",
        {
            "scene": d["name"],
            "model": d["model"],
            "cells": d["cells"],
            **({} if topo.is_open_chain else {"topology": topo.as_dict()}),
            "t_end_s": d["t_end_s"],
            "accuracy": d["accuracy"],
            "params": d["params"],
            "model_options": d["model_options"],
            "perturbation": d["perturbation"],
        },
        out,
    )
    if summary:
        observable_attrs(summary, out)
        if summary.get("dispersion"):
            _flat("theory", {k: v for k, v in summary["dispersion"].items()}, out)
    prov = (summary or {}).get("provenance") or provenance()
    _flat("provenance", prov, out)
    return out


def load_scene(scene: str | Scene, overrides: Overrides = None, accuracy: str | None = None) -> Scene:
    """A validated Scene from a shipped name / TOML path (or a Scene, returned with the overrides applied)."""
    over = override_list(overrides) + ([f'accuracy="{accuracy}"'] if accuracy else [])
    if hasattr(scene, "as_dict") and not isinstance(scene, str):
        if not over:
            return scene
        # the Scene as it is (a dataclasses.replace of a loaded one included), then the overrides
        return scene_from_dict(apply_overrides(scene_table(scene), over), scene.source)
    return _load(str(scene), over)


def list_scenes() -> list[str]:
    return [n for n, _, _ in _ls()]


def run(
    scene: str | Scene = "default",
    overrides: Overrides = None,
    accuracy: str | None = None,
    *,
    progress: bool = False,
    trackers: Sequence[Tracker] = (),
) -> RunResult:
    """Run a scene (shipped name, .toml path or Scene) and return its RunResult.

    overrides: {"params.sigma": 0.05, "perturbation.1.torque_Nm": 0.01, "t_end_s": 2} or ["KEY=VALUE", ...]
    (the keys of ``run --set``); accuracy: "fast" | "balanced" | "exact" (docs/accuracy.md).
    Raises ConfigError (bad scene or key) or NumericalInstability (the run blew up).
    """
    from ..analysis.summary import summarize
    from ..controller import run_scene

    sc = load_scene(scene, overrides, accuracy)
    res = run_scene(sc, progress=progress, trackers=list(trackers))
    summary = summarize(sc, res)
    return RunResult(sc, res.t, res.alpha, res.beta, summary, res.wall_s, res.info)
