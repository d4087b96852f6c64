"""The one run layout's arrays and its NPZ file, numpy only: what the emulator's runs, the rig logger's captures and
the experiment runner's repeats are written in, and he.load (host_emulator.workbench.datasets) reads.

`write_npz` writes the layout's arrays (time, cell, alpha, beta, and any of VARIABLES / EXTRA_ARRAYS) with the
attributes as one JSON string, atomically (`save_npz_atomic`: a temporary name, fsync, rename); `logger_layout`
turns the logger's cycle x cell arrays (protocol.capture.rows_to_arrays) into the layout's arrays. The layout
itself (format ``metacell-run/1``) is described in host_emulator/workbench/datasets.py and docs/datapath.md.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from protocol.capture import partial_cycles
from protocol.codec import RAD_PER_COUNT

FORMAT = "metacell-run/1"
# name -> (units, long name)
VARIABLES: dict[str, tuple[str, str]] = {
    "alpha": ("rad", "tall (alpha, honey) cylinder angle, CCW positive"),
    "beta": ("rad", "short (beta) cylinder angle, CCW positive"),
    "torque_alpha": ("N m", "reaction torque commanded on the alpha cylinder"),
    "torque_beta": ("N m", "reaction torque commanded on the beta cylinder"),
    "flags": ("1", "CELL_SAMPLE flags: ENABLED 1, BEMF 2, PERTURBING 4, PENDING 8, FAULT 16; -1 = no sample"),
    "sample_time": ("s", "the primary's clock when the cell was sampled"),
    "alpha_counts": ("count", "alpha encoder counts (400 per revolution)"),
    "beta_counts": ("count", "beta encoder counts (400 per revolution)"),
    "host_time": ("s", "laptop clock (Unix time) when the sample was received"),
}
EXTRA_ARRAYS = ("cycle", "segment", "partial", "gaps")  # rig captures: per-row cycle, segment, partial; gap table


def logger_layout(arr: Mapping[str, np.ndarray], t0: float | None = None) -> dict[str, Any]:
    """The logger's cycle x cell arrays (SampleDecoder.arrays(), or an old logger NPZ) as this layout's arrays (numpy
    only): row time = the mean primary clock of the row's samples minus t0 (default: the first row's), as the
    experiment runner's series; cells without a sample in a row are NaN (never held). Key t_origin_s: that t0."""
    ts = np.asarray(arr["t_s"], dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # rows of a cell-less segment
        t = np.nanmean(ts, axis=1) if ts.size else np.zeros(0)
    keep = np.isfinite(t)
    if t0 is None:
        t0 = float(t[keep][0]) if keep.any() else 0.0
    a_all = np.asarray(arr["alpha_counts"], dtype=float)
    a = a_all[keep]
    b = np.asarray(arr["beta_counts"], dtype=float)[keep]
    if "partial" in arr:
        partial = np.asarray(arr["partial"], dtype=bool)
    else:  # a logger NPZ written before the flag
        partial = partial_cycles(np.asarray(arr["segment"]), a_all)
    return {
        "time": t[keep] - t0,
        "cell": np.asarray(arr.get("cells", np.arange(1, a.shape[1] + 1))),
        "alpha": a * RAD_PER_COUNT,
        "beta": b * RAD_PER_COUNT,
        "sample_time": ts[keep] - t0,
        "alpha_counts": a,
        "beta_counts": b,
        "flags": np.asarray(arr["flags"], dtype=np.int16)[keep],
        "host_time": np.asarray(arr["host_time"], dtype=float)[keep],
        "cycle": np.asarray(arr["cycle"])[keep],
        "segment": np.asarray(arr["segment"])[keep],
        "partial": partial[keep],
        "gaps": np.asarray(arr["gaps"]).reshape(-1, 4),
        "t_origin_s": t0,
    }


def _json_attrs(attrs: Mapping[str, Any]) -> str:
    def conv(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, (np.integer,)):
            return int(v)
        if isinstance(v, (np.floating,)):
            return float(v) if math.isfinite(v) else None
        return v

    return json.dumps({k: conv(v) for k, v in attrs.items()}, allow_nan=False, default=str)


def save_npz_atomic(path: str | Path, arrays: Mapping[str, Any]) -> Path:
    """np.savez_compressed to <path>.tmp, fsync, rename over <path>: a reader never sees a cut or empty NPZ (a full
    disk or a kill leaves the previous file or none, never a 0-byte one). As numpy, '.npz' is appended to a name
    without it; returns the path written."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def write_npz(path: str | Path, arrays: Mapping[str, Any], attrs: Mapping[str, Any]) -> Path:
    """Write this layout's arrays (time, cell, alpha, beta, and any of VARIABLES / EXTRA_ARRAYS) and attributes as
    NPZ, numpy only (the logger writes its captures with it), atomically (save_npz_atomic); returns the path."""
    out: dict[str, Any] = {
        "format": np.array(FORMAT),
        "attrs": np.array(_json_attrs({"format": FORMAT, **attrs})),
    }
    for name in ("time", "cell", *VARIABLES, *EXTRA_ARRAYS):
        if name in arrays and arrays[name] is not None:
            out[name] = np.asarray(arrays[name])
    missing = [k for k in ("time", "cell", "alpha", "beta") if k not in out]
    if missing:
        raise ValueError(f"write_npz: missing {', '.join(missing)}")
    return save_npz_atomic(path, out)
