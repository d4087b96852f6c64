"""What a sweep's points hold: the observables and their units, the string fields, the outcome of a point, and the
plain coordinate names of the swept keys."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import xarray as xr


OBSERVABLES = {  # name -> units (NaN in the dataset when a run does not report it)
    "domain_walls": "1",
    "pattern_wavelength_cells": "cells",
    "dominant_mode": "1",
    "pattern_period_cells": "cells",
    "amplitude_rad": "rad",
    "oscillation_period_s": "s",
    "growth_rate_per_s": "1/s",
    "at_rest": "1 (true) / 0 (false)",
    "steady": "1 (true) / 0 (false)",
    "theory_fastest_lambda_cells": "cells",
    "theory_fastest_growth_per_s": "1/s",
    "wall_s": "s",
    "dominant_wavelength_cells": "cells",  # a sheet's (analysis.pattern2d); NaN on a chain
}


BANDS = {"theory_band_lo_cells": "cells", "theory_band_hi_cells": "cells"}  # per unstable interval (dim band)


STRINGS = ("regime", "outcome", "status", "error", "pattern_kind")  # pattern_kind: a sheet's, "" on a chain


PATTERN_KINDS = ("stripes", "spots", "labyrinth", "rest", "oscillation")  # analysis.pattern2d's kinds, in figure order


OUTCOMES = ("rest", "pattern", "oscillation", "moving", "failed")


def _num(v):
    if v is None:
        return float("nan")
    if isinstance(v, bool):
        return float(v)
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def outcome_of(r: dict) -> str:
    """A point's outcome from its observables: rest, pattern (steady with domain walls), oscillation (a temporal
    period found, not at rest), moving (neither), failed."""
    if r.get("status") == "failed":
        return "failed"
    if r.get("at_rest") == 1:
        return "rest"
    if math.isfinite(_num(r.get("oscillation_period_s"))):
        return "oscillation"
    if r.get("steady") == 1 and _num(r.get("domain_walls")) > 0:
        return "pattern"
    return "moving"


def coord_names(keys) -> dict[str, str]:
    """Plain coordinate names for swept keys, usable with ds.sel(...) and as attributes: the last part of the key
    (params.sigma -> sigma, perturbation.1.torque_Nm -> torque_Nm), the whole key with '_' for '.' where two
    keys would share a name or a name is a variable's (regime, status, ...)."""
    keys = list(keys)
    last = [k.split(".")[-1] for k in keys]
    reserved = set(OBSERVABLES) | set(BANDS) | set(STRINGS) | {"seed", "band", "theory_band_kind"}
    out = {}
    for k, name in zip(keys, last):
        if k == "seed":
            out[k] = "seed"
        elif last.count(name) > 1 or name in reserved or not name.isidentifier():
            out[k] = k.replace(".", "_")
        else:
            out[k] = name
    return out


def _coord(ds: xr.Dataset, key: str) -> str | None:
    """The coordinate of a swept key (by its 'key' attribute, or an old dataset's coordinate named by the key)."""
    for name, c in ds.coords.items():
        if c.attrs.get("key") == key:
            return str(name)
    return key if key in ds.coords else None
