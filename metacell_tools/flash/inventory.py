"""The board inventory: which USB serial number is which cell (1..16) or the primary."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from .addresses import CELL_COUNT, cell_address

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


def validate(boards: list[Board]) -> list[Board]:
    """Check roles, cell numbers and uniqueness; return boards sorted cells 1..16, primary."""
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
            if isinstance(b.cell, bool) or not isinstance(b.cell, int) or not 1 <= b.cell <= CELL_COUNT:
                errors.append(f"board {b.serial}: cell must be 1..{CELL_COUNT}, got {b.cell!r}")
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
    boards = []
    for i, e in enumerate(raw):
        if not isinstance(e, dict) or set(e) - {"serial", "role", "cell", "note"}:
            raise InventoryError(f"{path}: boards[{i}] must be an object with serial, role[, cell, note]")
        boards.append(Board(e.get("serial", ""), e.get("role", ""), e.get("cell")))
    return validate(boards)


def save(path: str | Path, boards: list[Board]) -> None:
    """Write atomically (validated first, so a bad set never reaches the disk)."""
    boards = validate(boards)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    entries = []
    for b in boards:
        e: dict[str, str | int | None] = {"serial": b.serial, "role": b.role}
        if b.role == "cell":
            e["cell"] = b.cell
        entries.append(e)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps({"format": FORMAT, "boards": entries}, indent=2) + "\n")
    tmp.replace(path)


def assign(boards: list[Board], serial: str, target: str, replace: bool = False) -> list[Board]:
    """New inventory with `serial` as cell N ("1".."16") or "primary".

    Refuses to take a slot another board holds unless replace=True (board swap); the
    serial's previous slot, if any, is released.
    """
    if target == "primary":
        new = Board(serial, "primary")
    else:
        try:
            cell = int(target)
        except ValueError:
            raise InventoryError(f"target must be 1..{CELL_COUNT} or 'primary', got {target!r}") from None
        if not 1 <= cell <= CELL_COUNT:
            raise InventoryError(f"cell must be 1..{CELL_COUNT}, got {cell}")
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
    return validate(kept + [new])
