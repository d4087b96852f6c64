"""Cost against cells (16..4096) and against simulated time, for the lattice and hil models (one core).

Two figures per size: the compiled kernel alone (one he_advance / he_hil_run call over the whole span, so no
Python in the loop) and the end-to-end controller run (run_solver: the solver's advance_many records up to 256
output samples per C call, so the Python cost is per chunk, not per 10 ms sample). Linear scaling means a
constant cost per cell-second; the spread max/min over the sizes is printed.
"""

from __future__ import annotations

from collections.abc import Callable

from ..controller import build_solver, run_solver
from ..models.hil import HilSolver
from ..models.lattice import LatticeSolver
from ..scene import load_scene
from .common import clock, fmt, table

CELLS = (16, 64, 256, 1024, 4096)


def _scene(model, cells, t_end_s, dt_out=0.01):
    name = "exp3_single_sigma9" if model == "lattice" else "default"
    return load_scene(name, [f"t_end_s={t_end_s}", f"cells={cells}", f"model_options.dt_out={dt_out}"])


def kernel_time(model_name: str, cells: int, t_end_s: float) -> float:
    """Wall time of the compiled loop alone over t_end_s (one C call), best of 3."""
    sc = _scene(model_name, cells, t_end_s)

    def go() -> float:
        s = build_solver(sc, resolve=False)
        if not isinstance(s, (LatticeSolver, HilSolver)):
            raise TypeError(f"{model_name}: no compiled loop to time in {type(s).__name__}")
        lib = s.model.lib
        t0 = clock()
        if isinstance(s, LatticeSolver):  # s.h: the plant step (s)
            n = int(round(t_end_s / s.h))
            rc = lib.he_advance(s.model.plant, s.sid, s.h, n, s._pt, s._px, s._pv)
        else:  # s.h: the he_hil_t of the loop
            n = int(round(t_end_s * s.model.rate_hz))
            rc = lib.he_hil_run(s.h, n, s._pt, s._px, s._pv)
        if rc != lib.HE_OK:
            raise RuntimeError(f"{model_name} {cells} cells: rc {rc}")
        return clock() - t0

    return min(go() for _ in range(5))


def e2e_time(model_name: str, cells: int, t_end_s: float, dt_out: float = 0.01, repeat: int = 5) -> float:
    """Wall time of the controller run (run_solver: chunks of output samples per C call); the model and solver
    construction (a per-cell setup cost, not a per-cell-second one) is outside the timing. Best of `repeat`."""
    sc = _scene(model_name, cells, t_end_s, dt_out)
    best = float("inf")
    for _ in range(repeat):
        s = build_solver(sc, resolve=False)
        t0 = clock()
        run_solver(s, t_end_s)
        best = min(best, clock() - t0)
    return best


def scaling(quick: bool = False, log: Callable[..., None] = print) -> tuple[str, str, dict]:
    rows = []
    spreads = {}
    for model_name in ("lattice", "hil"):
        per: list[list[float]] = [[], [], []]
        for n in CELLS if not quick else (16, 256, 4096):
            cs = 800.0 if model_name == "lattice" else 400.0  # cell-seconds per measurement
            t_end = round(cs / n, 3)
            walls = [
                kernel_time(model_name, n, t_end),
                e2e_time(model_name, n, t_end, 0.01),
                e2e_time(model_name, n, t_end, 0.1),
            ]
            c = [w / (n * t_end) * 1e6 for w in walls]  # us per cell-second
            for i in range(3):
                per[i].append(c[i])
            rows.append([model_name, n, fmt(t_end), fmt(walls[0] * 1e3)] + [fmt(x) for x in c])
        spreads[model_name] = tuple(max(p) / min(p) for p in per)
    out = table(
        rows,
        [
            "model",
            "cells",
            "sim s",
            "kernel cpu ms",
            "kernel us/cell-s",
            "run us/cell-s (10 ms samples)",
            "run us/cell-s (100 ms samples)",
        ],
    )
    # against simulated time (16 cells)
    trows = []
    for model_name in ("lattice", "hil"):
        for t_end in (1.0, 4.0, 16.0) if not quick else (1.0, 4.0):
            e = e2e_time(model_name, 16, t_end)
            trows.append([model_name, 16, fmt(t_end), fmt(e * 1e3), fmt(e / t_end * 1e3)])
    tout = table(trows, ["model", "cells", "sim s", "cpu ms", "cpu ms per sim s"])
    return out, tout, spreads
