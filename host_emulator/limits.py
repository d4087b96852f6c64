"""Checks of a run's values before any work: finite, in range, fit the firmware's integers, memory and step count within
the machine.

`check_run(scene)` returns the first problem as one line (the CLI prints it and exits 2) or None.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .scene import Scene

INT32 = 2**31
MAX_CELL_STEPS = 1e10  # plant steps x cells: about an hour at the compiled loop's speed
FIRMWARE_PARAMS = ("k_ab", "k1", "k2", "sigma", "alpha_star")  # sent as int32 micro-units (uN*m/rad, urad)
RANGES = {  # physically meaningful ranges; outside them the solvers slow to a halt
    "band_scale": (1e-3, 100.0),
    "eta_scale": (1e-3, 1e3),
    "gamma": (1e-4, 1e3),
}
JITTER_MAX_COUNTS = 400.0  # one revolution of the encoder
POINTS_MAX = 256


def mem_available() -> float:
    """Bytes the machine can give (MemAvailable), or 8 GiB where unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return 8.0 * 2**30


def check_run(scene: Scene) -> str | None:
    p, o = scene.params, scene.options
    for name in FIRMWARE_PARAMS:
        if getattr(p, name, None) is None:
            continue
        per = name in p.per_cell_keys
        for j, v in enumerate(p.per_cell(name)):
            if not (math.isfinite(v) and abs(v) * 1e6 < INT32):
                where = f"params.{name}[{j + 1}] (cell {j + 1})" if per else f"params.{name}"
                return f"{where} = {v}: does not fit the firmware's int32 micro-units (|value| < {INT32 / 1e6:g})"
    for name, (lo, hi) in RANGES.items():
        v = getattr(p, name, None)
        if v is not None and not (math.isfinite(v) and lo <= v <= hi):
            return f"params.{name} = {v}: expected {lo:g}..{hi:g}"
    jit = o.noise.encoder_jitter_counts
    if not (math.isfinite(jit) and 0 <= jit <= JITTER_MAX_COUNTS):
        return f"model_options.noise.encoder_jitter_counts = {jit}: expected 0..{JITTER_MAX_COUNTS:g} (one revolution)"
    t_end = scene.t_end_s
    if not o.dt_out <= t_end:
        return f"model_options.dt_out = {o.dt_out} s: must not exceed t_end_s = {t_end} s"
    if o.dt is not None and not o.dt <= o.dt_out:
        return f"model_options.dt = {o.dt} s: must not exceed dt_out = {o.dt_out} s"
    if o.dt is not None:
        steps = t_end / o.dt * scene.cells
        if steps > MAX_CELL_STEPS:
            return (
                f"model_options.dt = {o.dt} s over t_end_s = {t_end} s is {steps:.3g} cell steps "
                f"(limit {MAX_CELL_STEPS:.0e}, about an hour): use a larger dt or a shorter run"
            )
    n_out = t_end / o.dt_out + 1
    per_sample = scene.cells * 2 * 8 * 4  # alpha, beta float64, a few working copies
    if scene.model == "continuum":
        if o.points_per_cell > POINTS_MAX:
            return f"model_options.points_per_cell = {o.points_per_cell}: expected 1..{POINTS_MAX}"
        per_sample *= o.points_per_cell
    need = n_out * per_sample
    avail = mem_available()
    if need > 0.5 * avail:
        return (
            f"t_end_s = {t_end} s every dt_out = {o.dt_out} s needs about {need / 2**30:.3g} GiB of output "
            f"arrays; this machine has {avail / 2**30:.3g} GiB available"
        )
    return None


def check_out_dir(path: str | os.PathLike) -> str | None:
    """Create the output directory now (before simulating); why not, or None."""
    from pathlib import Path

    path = Path(path)
    if path.exists() and not path.is_dir():
        return f"--out {path}: exists and is not a directory"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return f"--out {path}: cannot create it: {e.strerror or e}"
    if not os.access(path, os.W_OK):
        return f"--out {path}: not writable"
    return None
