"""What plots and the run catalogue take: a RunResult (he.run's or the controller's), an xarray Dataset of the run
layout (r.to_xarray(), he.load(...)), a run directory or a capture path, read into one view (RunView)."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..analysis.stability import Theory
    from ..params import Params
    from ..scene import Scene
    from ..topology import Topology

__all__ = ["RunView", "as_run", "params_from_attrs"]


@dataclass
class RunView:
    """One run or capture as plots read it: time (T,), alpha and beta (T, N) in cell order (a sheet's row by row;
    NaN where a cell sent no sample), the Scene when the input carries one (a RunResult), and the dataset's
    attributes (scene name, source, params.*, model, perturbation.*, topology.*, provenance.*) otherwise."""

    time: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    scene: Scene | None = None
    attrs: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        if self.scene is not None:
            return self.scene.name
        name = str(self.attrs.get("scene") or "")
        if name:
            return name
        origin = str(self.attrs.get("origin") or "")
        return Path(origin).name if origin else ""

    @property
    def source(self) -> str:
        if self.scene is not None:
            return str(self.attrs.get("source") or f"emulator:{self.scene.model}")
        return str(self.attrs.get("source") or "unknown")

    @property
    def topology(self) -> Topology:
        """The run's lattice: the scene's, else the topology.* attributes', else the open chain of its N cells."""
        from ..topology import Topology
        from .datasets import topology_of_attrs

        if self.scene is not None:
            return self.scene.topology
        return topology_of_attrs(self.attrs) or Topology.chain(self.alpha.shape[1])

    @property
    def params(self) -> Params | None:
        """The run's parameters: the scene's, else rebuilt from the params.* attributes (None for a capture)."""
        if self.scene is not None:
            return self.scene.params
        return params_from_attrs(self.attrs, self.alpha.shape[1])

    def theory(self) -> Theory | None:
        """The linear theory of the model that ran (analysis.summary.theory_for); None when params are unknown."""
        from ..analysis.stability import theory_of

        if self.scene is not None:
            from ..analysis.summary import theory_for

            return theory_for(self.scene)
        p = self.params
        model = str(self.attrs.get("model") or "")
        if p is None or not model or model == "rig":
            return None
        try:
            return theory_of(model, p, bool(int(self.attrs.get("model_options.inertia", 1))))
        except (KeyError, ValueError):
            return None

    def final(self, var: str = "alpha") -> np.ndarray:
        """Each cell's last finite sample (N,) (NaN for a cell that never sent one)."""
        a = self.alpha if var == "alpha" else self.beta
        out = np.full(a.shape[1], np.nan)
        for j in range(a.shape[1]):
            ok = np.flatnonzero(np.isfinite(a[:, j]))
            if len(ok):
                out[j] = a[ok[-1], j]
        return out


def params_from_attrs(attrs: dict, cells: int) -> Params | None:
    """Params from a dataset's flat ``params.*`` attributes (booleans stored as 0/1, per-cell laws as arrays), or
    None when there are none or they do not make a valid parameter set."""
    from ..models import ConfigError
    from ..params import Params
    from ..scene import _parse_params

    kinds = {f.name: f.default for f in dataclasses.fields(Params)}
    d: dict[str, Any] = {}
    for k, v in attrs.items():
        if not k.startswith("params.") or k.count(".") != 1:
            continue
        key = k.split(".", 1)[1]
        if key == "cells":
            cells = int(v)
            continue
        if key in ("shape", "lattice", "boundary"):  # the lattice: the topology.* attributes say it
            continue
        if isinstance(v, np.ndarray):
            v = [float(x) for x in v.ravel()]
        elif isinstance(v, np.generic):
            v = v.item()
        if isinstance(kinds.get(key), bool) and isinstance(v, (int, float)):
            v = bool(v)
        d[key] = v
    if not d:
        return None
    from .datasets import topology_of_attrs

    try:
        topo = topology_of_attrs(attrs)
        return _parse_params(d, cells if topo is None else topo.n, topo)
    except (ConfigError, ValueError, TypeError):
        return None


def _from_dataset(ds: Any) -> RunView:
    if "alpha" not in ds or "time" not in ds.coords:
        raise TypeError("a Dataset of the run layout (dims time, cell; variables alpha, beta) was expected")
    from .datasets import cell_values

    alpha = cell_values(ds, "alpha")
    beta = cell_values(ds, "beta") if "beta" in ds else np.full(alpha.shape, np.nan)
    return RunView(
        np.asarray(ds["time"].values, float),
        np.asarray(alpha, float),
        np.asarray(beta, float),
        attrs=dict(ds.attrs),
    )


def as_run(run: Any) -> RunView:
    """A RunView of any input plots take: he.run's RunResult, the controller's RunResult (t, alpha, beta), an xarray
    Dataset of the run layout, or a path (str or os.PathLike) of a run directory, experiment directory, capture or
    log that he.load opens. A LoadError (one line) for a path it cannot read; TypeError for anything else."""
    if isinstance(run, RunView):
        return run
    if isinstance(run, (str, os.PathLike)):
        from .datasets import load

        return _from_dataset(load(Path(run)))
    if hasattr(run, "data_vars") and hasattr(run, "attrs"):
        return _from_dataset(run)
    if hasattr(run, "alpha") and hasattr(run, "beta"):
        t = getattr(run, "time", None)
        if t is None:
            t = run.t
        scene = getattr(run, "scene", None)
        scene = scene if hasattr(scene, "params") else None
        summary = getattr(run, "summary", None) or {}
        attrs = {"source": summary.get("source")} if summary.get("source") else {}
        return RunView(np.asarray(t, float), np.asarray(run.alpha, float), np.asarray(run.beta, float), scene, attrs)
    raise TypeError(
        f"expected a RunResult, an xarray Dataset, a run directory or a capture path, got {type(run).__name__}"
    )
