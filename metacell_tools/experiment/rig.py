"""The rig a scene runs on: its topology from the rig config (metacell_tools.rigtools.rigconfig, rig/rig.toml) as
host_emulator/topology.py defines it, and the scene as run there (a sheet rig's scene takes the rig's shape, so the
summary, the trajectories and their analysis treat the capture as a sheet)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from host_emulator.topology import Topology, TopologyError
from metacell_tools.rigtools import rigconfig
from protocol.wire import N_CELLS

from .plan import PlanError

AS_BUILT = Topology.chain(N_CELLS)  # the rig as built: 16 cells banded as a chain

if TYPE_CHECKING:
    from host_emulator.scene import Scene


def rig_topology(path: str | None = None) -> Topology:
    """The rig's topology from its config (path; default rig/rig.toml, else the rig as built: a chain of 16)."""
    try:
        cfg = rigconfig.read(path)
        return Topology.from_spec(cfg["cells"], cfg["lattice"], cfg["boundary"])
    except (rigconfig.RigConfigError, TopologyError) as e:
        raise PlanError(str(e)) from None


def on_rig(scene: Scene, rig: Topology) -> Scene:
    """The scene as it runs on the rig (PlanError when it cannot). On a chain, as always: cells 1..scene.cells of
    the rig (make_plan checks they exist). On a sheet, every cell of the rig, and the scene takes the rig's shape: a
    chain scene of as many cells runs with its parameters on the sheet; a scene naming another sheet is refused."""
    own = scene.params.topology
    where = f"the rig is a {rig.describe()} (rig config)"
    if not rig.is_sheet:
        if own.is_sheet:
            raise PlanError(f"the scene is a {own.describe()}; {where}")
        return scene  # make_plan checks its cells against the rig's
    if scene.cells != rig.n:
        raise PlanError(f"cells = {scene.cells}: {where}; a sheet runs with every cell banded")
    if own.is_sheet and (own.shape, own.kind, own.periodic) != (rig.shape, rig.kind, rig.periodic):
        raise PlanError(f"the scene is a {own.describe()}; {where}")
    params = dataclasses.replace(
        scene.params, shape=rig.shape, lattice=rig.kind, boundary="periodic" if rig.periodic else "open"
    )
    return dataclasses.replace(scene, params=params)
