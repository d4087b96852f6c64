"""Python view of protocol/definition.py: constants, cell addresses, CRC-8, map id, command frames and the shipped DBC.

Shared by the laptop tools and the host emulator (neither imports the other for wire facts).
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Iterable
from pathlib import Path

from . import definition as D

PROTOCOL_DIR = Path(__file__).resolve().parent
DBC_PATH = PROTOCOL_DIR / "metacell.dbc"

N_CELLS = D.N_CELLS  # the rig as built (16)
MAX_CELLS = D.MAX_CELLS  # the most cells a sheet's data path addresses (64)
ADDR_BASE = D.ADDR_BASE
REGISTERS = D.REGISTERS
RESULTS = D.RESULTS
RESULT_NAMES = {v: k for k, v in D.RESULTS.items()}
FRAMES = D.FRAMES
BLOCKS = D.BLOCKS
CELL_FLAGS = D.CELL_FLAGS
TYPE_SIZES = D.TYPE_SIZES
_FMT = {"u8": "B", "i8": "b", "u16": "H", "i16": "h", "u32": "I", "i32": "i", "b7": "7s"}
TYPE_RANGES = {"u8": (0, 0xFF), "i8": (-0x80, 0x7F), "u16": (0, 0xFFFF), "i16": (-0x8000, 0x7FFF)}
TYPE_RANGES |= {"u32": (0, 0xFFFFFFFF), "i32": (-0x80000000, 0x7FFFFFFF)}


# ---- cell addresses: cell j (1..MAX_CELLS) answers at ADDR_BASE + j - 1 -------------------------------------
def cell_address(cell: int) -> int:
    """7-bit I2C address of cell 1..MAX_CELLS (ValueError otherwise); the rig as built uses 1..N_CELLS."""
    if isinstance(cell, bool) or not isinstance(cell, int) or not 1 <= cell <= MAX_CELLS:
        raise ValueError(f"cell number must be an integer 1..{MAX_CELLS}, got {cell!r}")
    return ADDR_BASE + cell - 1


def cell_of_address(addr: int) -> int:
    """Inverse of cell_address: the cell number owning 7-bit address addr (ValueError otherwise)."""
    if isinstance(addr, bool) or not isinstance(addr, int):
        raise ValueError(f"address must be an integer, got {addr!r}")
    cell = addr - ADDR_BASE + 1
    if not 1 <= cell <= MAX_CELLS:
        raise ValueError(
            f"address 0x{addr:02x} belongs to no cell (cells use 0x{ADDR_BASE:02x}..0x{ADDR_BASE + MAX_CELLS - 1:02x})"
        )
    return cell


def per_cell_ids(d=D) -> dict[str, range]:
    """Every per-cell frame's CAN ids (base + 1 .. base + MAX_CELLS); ValueError when two frames' ids overlap, one
    collides with a single frame's id or leaves the 11-bit range."""
    ids = {name: range(f["base"] + 1, f["base"] + d.MAX_CELLS + 1) for name, f in d.FRAMES.items() if f["per_cell"]}
    single = {f["base"]: name for name, f in d.FRAMES.items() if not f["per_cell"]}
    seen: dict[int, str] = dict(single)
    for name, r in ids.items():
        if r[-1] > 0x7FF:
            raise ValueError(f"{name}: cell {d.MAX_CELLS}'s id 0x{r[-1]:03X} is not an 11-bit id")
        for i in r:
            if i in seen:
                raise ValueError(f"CAN id 0x{i:03X} is both {seen[i]} and {name} (cell {i - r[0] + 1})")
            seen[i] = name
    return ids


# ---- checksums and the map id ------------------------------------------------------------------------------
def crc8(data: bytes, crc: int = D.CRC8_INIT) -> int:
    """Bitwise reference CRC-8 (poly D.CRC8_POLY, MSB first): independent of the C table."""
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ D.CRC8_POLY) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def crc16_ccitt(data: bytes, crc: int = 0xFFFF) -> int:
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def map_id(d=D) -> int:
    """MC_PROTO_MAP_ID: CRC-16 of a canonical text of every layout and wire unit (changes whenever one does)."""
    canon = repr(
        (
            d.PROTO_VERSION,
            d.ADDR_BASE,
            d.N_CELLS,
            d.CRC8_POLY,
            d.CRC8_INIT,
            sorted((k, v["id"], [f[:2] for f in v["fields"]]) for k, v in d.BLOCKS.items()),
            sorted((k, v["id"], [f[:2] for f in v["payload"]]) for k, v in d.REGISTERS.items()),
            sorted(d.RESULTS.items()),
            sorted(d.CELL_FLAGS.items()),
            sorted((k, v["base"], [s[:4] for s in v.get("signals", [])]) for k, v in d.FRAMES.items()),
            sorted((k, u["si"], u.get("micro"), u.get("lsb")) for k, u in d.UNITS.items()),
        )
    )
    return crc16_ccitt(canon.encode())


# ---- layouts, payloads, frames -----------------------------------------------------------------------------
def offsets(fields) -> tuple[list[tuple[str, str, int]], int]:
    """[(name, type, byte offset)] of a block/payload/signal list, and its total length."""
    off, out = 0, []
    for f in fields:
        out.append((f[0], f[1], off))
        off += TYPE_SIZES[f[1]]
    return out, off


def layout(fields) -> tuple[str, list[str]]:
    """struct format (little-endian) and field names of a block/payload/signal list."""
    return "<" + "".join(_FMT[f[1]] for f in fields), [f[0] for f in fields]


def block_len(name: str) -> int:
    return offsets(BLOCKS[name]["fields"])[1]


def pack_payload(reg: str, **values) -> bytes:
    """Register payload bytes from raw register values (ValueError on a missing/extra field or overflow)."""
    if reg not in REGISTERS:
        raise ValueError(f"unknown command register {reg!r}; one of {sorted(REGISTERS)}")
    r = REGISTERS[reg]
    fmt, names = layout(r["payload"])
    if set(names) != set(values):
        raise ValueError(f"register {reg}: payload fields are {names}, got {sorted(values)}")
    try:
        return struct.pack(fmt, *(values[n] for n in names))
    except struct.error as e:
        raise ValueError(f"register {reg}: {e}") from None


def unpack_payload(reg: str, data: bytes) -> dict:
    fmt, names = layout(REGISTERS[reg]["payload"])
    return dict(zip(names, struct.unpack(fmt, data)))


def i2c_write_frame(j: int, reg: str, seq: int, payload: bytes) -> bytes:
    """Bytes of an I2C register write to cell j: reg seq payload crc (CRC also covers addr<<1)."""
    body = bytes([REGISTERS[reg]["id"], seq & 0xFF]) + payload
    return body + bytes([crc8(bytes([cell_address(j) << 1]) + body)])


def decode_block(name: str, data: bytes) -> dict:
    fmt, names = layout(BLOCKS[name]["fields"])
    return dict(zip(names, struct.unpack(fmt, data)))


def cmd_frame_id(j: int) -> int:
    cell_address(j)  # validates j
    return FRAMES["CMD"]["base"] + j


def cmd_data(reg: str, seq: int, **values) -> bytes:
    """CAN CMD payload: reg, seq, register payload (DLC = 2 + payload length)."""
    if reg not in REGISTERS:
        raise ValueError(f"unknown command register {reg!r}; one of {sorted(REGISTERS)}")
    return bytes([REGISTERS[reg]["id"], seq & 0xFF]) + pack_payload(reg, **values)


@functools.lru_cache(maxsize=1)
def database():
    """The shipped CAN database (cantools)."""
    import cantools

    return cantools.database.load_file(str(DBC_PATH))


def reassemble_blocks(chunks: Iterable[bytes]) -> dict:
    """{block name: decoded dict} from BLOCK_DATA payloads of one cell (CRC checked here too)."""
    parts: dict[int, dict[int, bytes]] = {}
    for d in chunks:
        parts.setdefault(d[0] >> 4, {})[d[0] & 15] = bytes(d[1:8])
    names = {b["id"]: k for k, b in BLOCKS.items()}
    out = {}
    for blk, p in parts.items():
        if blk not in names:
            continue
        name = names[blk]
        n = block_len(name)
        raw = b"".join(p[k] for k in sorted(p))[:n]
        if len(raw) == n and crc8(raw[:-1]) == raw[-1]:
            out[name] = decode_block(name, raw)
    return out


def frame_kind(arbitration_id: int, cells: int = N_CELLS) -> tuple[str, int | None]:
    """(frame name, cell number or None) of a CAN id of a rig of `cells` cells (the rig as built's 16 unless told:
    a bigger sheet's frames are foreign to it), ('UNKNOWN', None) otherwise."""
    for name, f in FRAMES.items():
        if f["per_cell"]:
            j = arbitration_id - f["base"]
            if 1 <= j <= cells:
                return name, j
        elif arbitration_id == f["base"]:
            return name, None
    return "UNKNOWN", None
