"""The board inventory: which USB serial number is which cell (1..N: 16 on the rig as built, a sheet up to 64) or the
primary, and how many cells the rig has (the JSON's "cells", written only when not 16)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from .addresses import CELL_COUNT, MAX_CELL_COUNT, cell_address

FORMAT = "metacell-boards-1"
DEFAULT_PATH = Path("rig") / "boards.json"


class InventoryError(ValueError):
    """The inventory is malformed or contradicts itself."""


@dataclass(frozen=True)
class Board:
    serial: str
    role: str  # "cell" or "primary"
    cell: int | None = None

    @property
    def addr(self) -> int | None:
        return cell_address(self.cell) if self.role == "cell" and self.cell is not None else None

    @property
    def name(self) -> str:
        if self.role == "primary":
            return "primary"
        return f"cell {self.cell} (0x{self.addr:02x})"


def check_cells(cells: object) -> int:
    """The rig's cell count, 1..MAX_CELL_COUNT (InventoryError otherwise)."""
    if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= MAX_CELL_COUNT:
        raise InventoryError(f"cells must be 1..{MAX_CELL_COUNT} (a sheet's most), got {cells!r}")
    return cells


def validate(boards: list[Board], cells: int = CELL_COUNT) -> list[Board]:
    """Check roles, cell numbers (1..cells) and uniqueness; return boards sorted cells 1..cells, primary."""
    cells = check_cells(cells)
    errors = []
    by_serial: dict[str, Board] = {}
    by_cell: dict[int, list[Board]] = {}
    primaries = []
    for b in boards:
        if not isinstance(b.serial, str) or not b.serial.strip():
            errors.append(f"board {b!r}: serial number must be a non-empty string")
            continue
        if b.serial in by_serial:
            errors.append(f"serial {b.serial} is listed twice")
        by_serial[b.serial] = b
        if b.role == "primary":
            if b.cell is not None:
                errors.append(f"primary {b.serial} must not carry a cell number")
            primaries.append(b)
        elif b.role == "cell":
            if isinstance(b.cell, bool) or not isinstance(b.cell, int) or not 1 <= b.cell <= cells:
                errors.append(f"board {b.serial}: cell must be 1..{cells}, got {b.cell!r}")
            else:
                by_cell.setdefault(b.cell, []).append(b)
        else:
            errors.append(f"board {b.serial}: role must be 'cell' or 'primary', got {b.role!r}")
    for cell, owners in sorted(by_cell.items()):
        if len(owners) > 1:
            errors.append(
                f"two boards claim cell {cell} (address 0x{cell_address(cell):02x}): "
                + ", ".join(o.serial for o in owners)
            )
    if len(primaries) > 1:
        errors.append("more than one primary: " + ", ".join(p.serial for p in primaries))
    if errors:
        raise InventoryError("; ".join(errors))
    return sorted(boards, key=lambda b: (b.role != "cell", b.cell or 0))


def load(path: str | Path) -> list[Board]:
    """The boards of the inventory at path (validated against its cell count)."""
    return read(path)[0]


def load_cells(path: str | Path) -> int:
    """The rig's cell count the inventory at path records (16 when it says nothing)."""
    return read(path)[1]


def read(path: str | Path) -> tuple[list[Board], int]:
    """(boards, the rig's cell count) of the inventory at path; InventoryError when it is missing or malformed."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise InventoryError(
            f"no inventory at {path}: create it with `python -m metacell_tools.flash inventory --assign ...`"
        ) from exc
    except (OSError, json.JSONDecodeError) as exc:
        raise InventoryError(f"cannot read inventory {path}: {exc}") from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InventoryError(f"{path}: not a {FORMAT} inventory")
    raw = data.get("boards")
    if not isinstance(raw, list):
        raise InventoryError(f"{path}: 'boards' must be a list")
    try:
        cells = check_cells(data.get("cells", CELL_COUNT))
    except InventoryError as exc:
        raise InventoryError(f"{path}: {exc}") from None
    boards = []
    for i, e in enumerate(raw):
        if not isinstance(e, dict) or set(e) - {"serial", "role", "cell", "note"}:
            raise InventoryError(f"{path}: boards[{i}] must be an object with serial, role[, cell, note]")
        boards.append(Board(e.get("serial", ""), e.get("role", ""), e.get("cell")))
    return validate(boards, cells), cells


def save(path: str | Path, boards: list[Board], cells: int = CELL_COUNT) -> None:
    """Write atomically (validated first, so a bad set never reaches the disk); "cells" only for a rig other than the
    16 cells as built (so the rig's own inventory reads as before)."""
    boards = validate(boards, cells)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    entries = []
    for b in boards:
        e: dict[str, str | int | None] = {"serial": b.serial, "role": b.role}
        if b.role == "cell":
            e["cell"] = b.cell
        entries.append(e)
    tmp = path.with_suffix(path.suffix + ".tmp")
    doc: dict[str, object] = {"format": FORMAT, "boards": entries}
    if cells != CELL_COUNT:
        doc = {"format": FORMAT, "cells": cells, "boards": entries}
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    tmp.replace(path)


def assign(
    boards: list[Board], serial: str, target: str, replace: bool = False, cells: int = CELL_COUNT
) -> list[Board]:
    """New inventory with `serial` as cell N ("1".."cells") or "primary".

    Refuses to take a slot another board holds unless replace=True (board swap); the
    serial's previous slot, if any, is released.
    """
    if target == "primary":
        new = Board(serial, "primary")
    else:
        try:
            cell = int(target)
        except ValueError:
            raise InventoryError(f"target must be 1..{cells} or 'primary', got {target!r}") from None
        if not 1 <= cell <= cells:
            raise InventoryError(f"cell must be 1..{cells}, got {cell}")
        new = Board(serial, "cell", cell)
    holders = [
        b
        for b in boards
        if b.serial != serial
        and (
            (new.role == "primary" and b.role == "primary")
            or (new.role == "cell" and b.role == "cell" and b.cell == new.cell)
        )
    ]
    if holders and not replace:
        raise InventoryError(f"{new.name} is already board {holders[0].serial}; use --replace to swap it out")
    kept = [b for b in boards if b.serial != serial and b not in holders]
    return validate(kept + [new], cells)
