"""The rig config (rig/rig.toml): how the rig's cells are banded, in a scene's own keys — a chain of 16 as built, or a
sheet `cells = [rows, cols]` (optional `lattice = "square" | "hex"`, `boundary = "open" | "periodic"`).

This module only reads the file and checks its keys and types (the laptop tools below the experiment runner do not
import the emulator); what a lattice *is* — its cells, bonds and numbering — is host_emulator/topology.py's, which
the experiment runner builds from the same keys (metacell_tools.experiment.rig). Cells are numbered row by row:
cell = (row - 1) * cols + col, as docs/hardware.md bands them.

    # rig/rig.toml
    cells = [4, 4]          # 4 rows x 4 columns: the 16 cells re-banded as a square sheet
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from protocol.wire import MAX_CELLS, N_CELLS

DEFAULT_PATH = Path("rig") / "rig.toml"  # beside the flash tool's inventory, rig/boards.json
KEYS = ("cells", "lattice", "boundary")
LATTICES = ("chain", "square", "hex")
BOUNDARIES = ("open", "periodic")
AS_BUILT = {"cells": N_CELLS, "lattice": "chain", "boundary": "open"}  # the rig as built: a chain of 16


class RigConfigError(ValueError):
    """The rig config cannot be read or names no rig the data path serves (one line naming the key)."""


def read(path: str | Path | None = None) -> dict:
    """{"cells": n or [rows, cols], "lattice", "boundary"} of the rig config at path; without a path, rig/rig.toml
    when it exists, else the rig as built (a chain of 16 cells). RigConfigError when the file is unreadable, has
    another key, or its cells are not 1..MAX_CELLS in all."""
    if path is None:
        if not DEFAULT_PATH.is_file():
            return dict(AS_BUILT)
        path = DEFAULT_PATH
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise RigConfigError(f"rig config {path}: not a readable TOML file ({type(e).__name__}: {e})") from None
    unknown = sorted(set(doc) - set(KEYS))
    if unknown:
        raise RigConfigError(f"rig config {path}: unknown key(s) {', '.join(unknown)}; it holds {', '.join(KEYS)}")
    if "cells" not in doc:
        raise RigConfigError(f"rig config {path}: `cells` is missing (16, or [rows, cols] for a sheet)")
    cells = doc["cells"]
    sheet = isinstance(cells, list)
    dims = cells if sheet else [cells]
    if (
        len(dims) not in ((1, 2) if sheet else (1,))
        or not all(isinstance(d, int) and not isinstance(d, bool) and d >= 1 for d in dims)
        or _product(dims) > MAX_CELLS
    ):
        raise RigConfigError(
            f"rig config {path}: cells = {cells!r}: expected a number of cells or [rows, cols], "
            f"at most {MAX_CELLS} cells in all (I2C addresses 0x10..0x{0x10 + MAX_CELLS - 1:02X})"
        )
    if sheet and len(dims) == 1:
        cells, sheet = dims[0], False
    lattice = doc.get("lattice", "square" if sheet else "chain")
    boundary = doc.get("boundary", "open")
    if lattice not in LATTICES or (sheet and lattice == "chain") or (not sheet and lattice != "chain"):
        want = "square or hex" if sheet else "chain"
        raise RigConfigError(f"rig config {path}: lattice = {lattice!r}: cells = {cells!r} is a {want}")
    if boundary not in BOUNDARIES:
        raise RigConfigError(f"rig config {path}: boundary = {boundary!r}: expected one of {', '.join(BOUNDARIES)}")
    return {"cells": list(cells) if sheet else cells, "lattice": lattice, "boundary": boundary}


def n_cells(config: dict) -> int:
    """How many cells the rig config names (rows x cols for a sheet)."""
    return _product(config["cells"] if isinstance(config["cells"], list) else [config["cells"]])


def _product(dims: list[int]) -> int:
    n = 1
    for d in dims:
        n *= d
    return n
