"""sweep.nc's content: the finished points as an xarray Dataset, a dimension per swept key."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from metacell_common.provenance import provenance

from ..api import netcdf_attrs
from .schema import BANDS, OBSERVABLES, STRINGS, _num, coord_names, outcome_of

if TYPE_CHECKING:
    import xarray as xr

    from ...scene import Scene


def to_dataset(specs: list[dict], axes: dict, done: dict, base: Scene, definition: dict) -> xr.Dataset:
    """The xarray Dataset of a sweep: one dimension per swept key (plain names, the key in the coordinate's 'key'
    attribute; + seed), observables as variables, the theory's unstable intervals over a dimension 'band'."""
    import xarray as xr

    shape = tuple(len(v) for v in axes.values())
    names = coord_names(axes)
    dims = tuple(names[k] for k in axes)
    nb = max([1] + [len(r.get("theory_bands") or []) for r in done.values()])
    data = {k: np.full(shape, np.nan) for k in OBSERVABLES}
    bands = {k: np.full(shape + (nb,), np.nan) for k in BANDS}
    kinds = np.full(shape + (nb,), "", dtype=object)
    strs = {k: np.full(shape, "", dtype=object) for k in STRINGS}
    strs["status"][...] = "pending"
    for s in specs:
        ix = np.unravel_index(s["index"], shape)
        r = done.get(s["index"])
        if r is None:
            continue
        for k in OBSERVABLES:
            if k in r:
                data[k][ix] = _num(r[k])
        for b, (lo, hi, kind) in enumerate(r.get("theory_bands") or []):
            bands["theory_band_lo_cells"][ix + (b,)] = _num(lo)
            bands["theory_band_hi_cells"][ix + (b,)] = float("inf") if hi in ("inf", None) else _num(hi)
            kinds[ix + (b,)] = kind
        for k in STRINGS:
            strs[k][ix] = str(r.get(k, "") or "")
        if not strs["outcome"][ix]:
            strs["outcome"][ix] = outcome_of(r)  # points stored before outcomes were
    vars_: dict[str, tuple] = {k: (dims, v, {"units": OBSERVABLES[k]}) for k, v in data.items()}
    vars_.update({k: (dims + ("band",), v, {"units": BANDS[k]}) for k, v in bands.items()})
    vars_["theory_band_kind"] = (dims + ("band",), kinds.astype(str), {"long_name": "stationary / oscillatory"})
    vars_.update({k: (dims, v.astype(str)) for k, v in strs.items()})
    coords = {}
    for k, v in axes.items():
        arr = np.asarray(v)
        coords[names[k]] = (names[k], arr if arr.dtype.kind in "ifu" else arr.astype(str), {"key": k})
    ds = xr.Dataset(vars_, coords=coords)
    ds.attrs.update(netcdf_attrs(base))
    ds.attrs.update({f"provenance.{k}": v for k, v in provenance().items()})
    ds.attrs["sweep.definition"] = json.dumps(definition)
    ds.attrs["sweep.points"] = int(np.prod(shape))
    ds.attrs["sweep.failed"] = int((strs["status"] == "failed").sum())
    ds.attrs["source"] = f"emulator:{base.model}"
    return ds
