"""The run summary (summary.json): observables of a run's trajectories and the linear theory of the model that ran.

Analysis, not command-line code: ``python -m host_emulator run``, ``host_emulator.run``, sweeps and the rig's
experiment runner all build their summaries here.

A sheet (``params.topology.is_sheet``) adds the 2-D pattern measures (analysis.pattern2d, SHEET_KEYS); the chain's
keys that read the final profile as a chain (CHAIN_ONLY_KEYS: its walls' bond positions, free-end modes, the
least-squares and 2(N-1)/Z wavelengths) are null there, and domain_walls is the boundary length in bonds (the
number of bonds across which the sign field changes: on a chain, the same Z); its "dispersion" is null (the chain's
linear theory does not describe a sheet). A chain's summary is unchanged.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..provenance import provenance
from .observables import observables
from .stability import dispersion, theory_of

if TYPE_CHECKING:
    from ..controller import RunResult
    from ..params import Params
    from ..scene import Scene
    from .stability import Theory

__all__ = ["summarize", "dispersion_summary", "theory_for", "clean", "DISPERSION_KEYS", "SHEET_KEYS", "CHAIN_ONLY_KEYS"]

# the pattern measures a sheet's summary adds (analysis.pattern2d.measures; docs/patterns2d.md)
SHEET_KEYS = (
    "dominant_wavelength_cells",
    "dominant_wavevector",
    "orientation_deg",
    "pattern_kind",
    "boundary_length_cells",
    "defects",
)
# observables that read the final profile as a chain's: null on a sheet (the keys stay, so every reader finds them)
CHAIN_ONLY_KEYS = (
    "domain_wall_bonds",
    "pattern_wavelength_cells",
    "dominant_mode",
    "dominant_mode_lambda_cells",
    "pattern_period_cells",
)


def clean(v: Any) -> Any:
    """JSON-ready: numpy scalars/arrays to Python, non-finite floats to None (never NaN in a summary)."""
    if isinstance(v, dict):
        return {str(k): clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [clean(x) for x in v]
    if isinstance(v, np.ndarray):
        return [clean(x) for x in v.tolist()]
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, (np.integer, int)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v) if math.isfinite(v) else None
    return v


# the linear theory's keys in summary.json["dispersion"] (docs/workbench.md)
DISPERSION_KEYS = (
    "regime",
    "theory",
    "fastest_lambda_cells",
    "fastest_growth_per_s",
    "oscillation_period_s",
    "unstable_set_cells",
    "unstable_intervals",
)


def theory_for(scene: Scene) -> Theory:
    """The linear theory of the scene's model (analysis.stability.theory_of with the scene's inertia switch)."""
    return theory_of(scene.model, scene.params, scene.options.inertia)


@functools.lru_cache(maxsize=256)
def _dispersion_cached(params: Params, theory: Theory, cells: int) -> tuple[tuple[str, Any], ...]:
    if params.heterogeneous:  # cells with their own laws: the chain's eigenmodes (analysis.chain)
        from .chain import chain_summary

        d = chain_summary(params, theory)
        return tuple((k, d.get(k)) for k in DISPERSION_KEYS) + (("inertia", theory.inertia), ("per_cell", True))
    d = dispersion(params.uniform(), theory=theory, n_cells=cells)
    return tuple((k, d.get(k)) for k in DISPERSION_KEYS) + (("inertia", theory.inertia),)


def dispersion_summary(params: Params, theory: Theory, cells: int) -> dict:
    """The dispersion keys of summary.json for one parameter set and theory (the chain's eigenmodes, analysis.chain,
    when its cells' reaction laws differ; per_cell: true then), cached: a sweep over seeds and pushes
    asks for the same parameters many times, and the linear theory costs as much as the 10 s run itself (Params
    and Theory are frozen). Returns a fresh copy (the cached lists are never shared)."""
    return {k: copy.deepcopy(v) for k, v in _dispersion_cached(params, theory, cells)}


def summarize(scene: Scene, res: RunResult, *, source: str | None = None) -> dict:
    """summary.json content: run figures, observables of the trajectories, the linear theory of the model that ran,
    parameters and provenance. source: "emulator:<model>" (default), "rehearsal:<model>" or "rig"."""
    obs = observables(res.t, res.alpha, res.beta)
    topo = scene.params.topology
    if topo.is_sheet:
        from .pattern2d import measures

        pat = measures(res.t, res.alpha, topo)
        obs.update(dict.fromkeys(CHAIN_ONLY_KEYS), domain_walls=pat["boundary_length_cells"], **pat)
    disp: dict | None = None
    if not topo.is_sheet:  # the chain's linear theory; a sheet's is not wired in here yet (docs/patterns2d.md)
        try:
            disp = dispersion_summary(scene.params, theory_for(scene), scene.cells)
        except ImportError:
            disp = None
    d = scene.as_dict()
    ran, acc = _as_run(scene, res, source)
    out = {
        "scene": scene.name,
        "model": scene.model,
        "source": source or f"emulator:{scene.model}",
        "t_end_s": float(res.t[-1]),
        "wall_s": res.wall_s,
        "realtime_factor": res.realtime_factor,
        **obs,
        "dispersion": disp,
        "solver": res.info,
        "params": d["params"],
        "model_options": d["model_options"] if ran is None else dataclasses.asdict(ran),
        "perturbation": d["perturbation"],
        "provenance": provenance(),
    }
    if acc is not None:
        out["accuracy"] = acc
    if getattr(scene, "model_reason", ""):
        out["model_choice"] = {"question": scene.question, "reason": scene.model_reason}
    return clean(out)


def _as_run(scene: Scene, res: RunResult, source: str | None) -> tuple[Any, dict | None]:
    """(the ModelOptions the run used, summary.json's "accuracy" record), or (None, None) for a summary of data
    the emulator did not produce here (the rig, a rehearsal's recording) that carries no options: its
    model_options stay the scene's. The options come from the solver (RunResult.options), else from the scene's
    preset resolved again (accuracy.resolve_options: what build_solver applies)."""
    from ..accuracy import KNOB_KEYS, record, resolve_options
    from ..models.options import ModelOptions

    ran = getattr(res, "options", None)
    if ran is None:
        if source is not None and not source.startswith("emulator"):
            return None, None
        ran = resolve_options(
            scene.model, scene.params, scene.perturbations, scene.options, scene.accuracy, scene.explicit_options
        )
    pure = None  # the preset's own options, only needed where the scene set a knob itself
    if any(k in KNOB_KEYS for k in scene.explicit_options):
        base = dataclasses.replace(scene.options, **{k: getattr(ModelOptions(), k) for k in KNOB_KEYS})
        pure = resolve_options(scene.model, scene.params, scene.perturbations, base, scene.accuracy)
    return ran, record(scene.model, scene.accuracy, scene.options, ran, scene.explicit_options, pure)
