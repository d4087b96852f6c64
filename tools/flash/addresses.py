"""The one cell-number -> I2C address mapping of the rig (import it; never re-derive it)."""

from __future__ import annotations

CELL_COUNT = 16
ADDR_BASE = 0x10
# 7-bit addresses the I2C specification reserves (general call, CBUS, HS mode, 10-bit...)
RESERVED = frozenset(range(0x00, 0x08)) | frozenset(range(0x78, 0x80))


def cell_address(cell: int) -> int:
    """7-bit I2C address of cell 1..16: 0x10 + cell - 1 (0x10..0x1f)."""
    if isinstance(cell, bool) or not isinstance(cell, int) or not 1 <= cell <= CELL_COUNT:
        raise ValueError(f"cell number must be an integer 1..{CELL_COUNT}, got {cell!r}")
    return ADDR_BASE + cell - 1


def address_cell(addr: int) -> int:
    """Inverse of cell_address: the cell number owning 7-bit address addr."""
    if isinstance(addr, bool) or not isinstance(addr, int):
        raise ValueError(f"address must be an integer, got {addr!r}")
    cell = addr - ADDR_BASE + 1
    if not 1 <= cell <= CELL_COUNT:
        raise ValueError(
            f"address 0x{addr:02x} belongs to no cell (cells use 0x{ADDR_BASE:02x}..0x{ADDR_BASE + CELL_COUNT - 1:02x})"
        )
    return cell


CELL_ADDRESSES: dict[int, int] = {j: cell_address(j) for j in range(1, CELL_COUNT + 1)}

assert not RESERVED & set(CELL_ADDRESSES.values())
