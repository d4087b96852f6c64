"""Cost per cell-step of the compiled lattice and hil loops on square sheets (16 x 16 .. 256 x 256) against chains.

    python -m host_emulator.benchmarks.sheet            # 16x16, 64x64, 256x256 periodic sheets and chains
    python -m host_emulator.benchmarks.sheet --quick    # 16x16 and 64x64 only

Each size runs the compiled loop alone (one he_advance / he_hil_run call, no Python in it) for a few steps after a
warm-up call, best of 3 on the process's CPU clock (benchmarks.common.clock), pinned to one core. The lattice
model's figure is CPU ns per cell and plant step (the scene exp3_single_sigma9's model options as it writes
them, no accuracy preset: symplectic Euler); the hil model's is CPU ns per cell and control tick (the default
scene: the firmware tick of every cell, then its plant steps; the open chain takes he_hil.c's fast plant step,
a sheet its edge-list twin). A flat column means the cost per cell does not grow with the sheet.
"""

from __future__ import annotations

import argparse
import os
import platform

from ..models.hil import HilModel
from ..models.lattice import LatticeModel
from ..scene import load_scene
from .common import clock, pin_one_core, table

SIDES = (16, 64, 256)


def _model(model_name: str, shape: tuple[int, ...], lattice: str, boundary: str):
    sc = load_scene("exp3_single_sigma9" if model_name == "lattice" else "default")
    n = shape[0] * shape[1] if len(shape) == 2 else shape[0]
    p = sc.params.with_overrides(
        cells=n, shape=shape if len(shape) == 2 else (), lattice=lattice, boundary=boundary, bemf_comp=False
    )
    cls = LatticeModel if model_name == "lattice" else HilModel
    return cls(p, list(sc.perturbations), sc.options), n


def cost(model_name: str, shape: tuple[int, ...], lattice: str = "square", boundary: str = "periodic", steps=20):
    """(cells, CPU ns per cell-step (lattice) or cell-tick (hil), plant steps per tick or None), best of 3."""
    m, n = _model(model_name, shape, lattice, boundary)
    s = m.solver()
    lib = m.lib
    best = float("inf")
    for k in range(4):  # the first call is a warm-up
        t0 = clock()
        if model_name == "lattice":
            rc = lib.he_advance(m.plant, s.sid, s.h, steps, s._pt, s._px, s._pv)
        else:
            rc = lib.he_hil_run(s.h, steps, s._pt, s._px, s._pv)
        dt = clock() - t0
        if rc != lib.HE_OK:
            raise RuntimeError(f"{model_name} {shape}: rc {rc}")
        if k:
            best = min(best, dt)
    return n, best / (n * steps) * 1e9, (s.substeps if model_name == "hil" else None)


def sheets(quick: bool = False, log=print, sides: tuple[int, ...] | None = None) -> str:
    """The table: per model and side, the periodic square sheet and the open chain of as many cells."""
    rows = []
    sides = sides or (SIDES[:2] if quick else SIDES)
    for model_name in ("lattice", "hil"):
        for side in sides:
            for what, shape, lat in (("square sheet", (side, side), "square"), ("open chain", (side * side,), "chain")):
                bnd = "periodic" if lat == "square" else "open"
                n, ns, sub = cost(model_name, shape, lat, bnd, steps=20 if side < 256 else 5)
                unit = "cell-step" if model_name == "lattice" else f"cell-tick ({sub} steps)"
                label = f"{side} x {side} periodic" if lat == "square" else f"{n} cells"
                rows.append([model_name, what, label, n, f"{ns:.0f}", unit])
                log(f"  {model_name} {what} {label}: {ns:.0f} ns per {unit}")
    return table(rows, ["model", "topology", "size", "cells", "CPU ns", "per"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.sheet", description=__doc__.splitlines()[0] if __doc__ else None
    )
    ap.add_argument("--quick", action="store_true", help="16 x 16 and 64 x 64 only")
    a = ap.parse_args(argv)
    where = pin_one_core()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, {where}, load {load:.1f}")
    print(sheets(a.quick, log=lambda *x: None))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
