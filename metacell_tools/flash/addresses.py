"""The rig's cell-number -> I2C address mapping for the flashing tool (defined once, in protocol/definition.py): the rig
as built has CELL_COUNT = 16 cells, a sheet up to MAX_CELL_COUNT = 64."""

from __future__ import annotations

from protocol.definition import ADDR_BASE, MAX_CELLS, N_CELLS
from protocol.wire import cell_address
from protocol.wire import cell_of_address as address_cell

CELL_COUNT = N_CELLS  # the rig as built, the inventory's default
MAX_CELL_COUNT = MAX_CELLS  # a sheet's most cells (addresses 0x10..0x4F)
# 7-bit addresses the I2C specification reserves (general call, CBUS, HS mode, 10-bit...)
RESERVED = frozenset(range(0x00, 0x08)) | frozenset(range(0x78, 0x80))

CELL_ADDRESSES: dict[int, int] = {j: cell_address(j) for j in range(1, CELL_COUNT + 1)}  # the rig as built

__all__ = ["ADDR_BASE", "CELL_COUNT", "MAX_CELL_COUNT", "RESERVED", "CELL_ADDRESSES", "cell_address", "address_cell"]

if RESERVED & {cell_address(j) for j in range(1, MAX_CELL_COUNT + 1)}:
    raise ImportError(f"protocol ADDR_BASE 0x{ADDR_BASE:02x} puts cells in the reserved I2C address ranges")
