"""Python view of protocol/definition.py: constants, cell addresses, CRC-8, command frames and the shipped DBC."""

from __future__ import annotations

import functools
import importlib.util
import struct
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL_DIR = ROOT / "protocol"
DBC_PATH = PROTOCOL_DIR / "metacell.dbc"


def _load(name: str, path: Path) -> ModuleType:
    """A module of protocol/ loaded by path (protocol/ is not an installed package)."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


D = _load("metacell_protocol_definition", PROTOCOL_DIR / "definition.py")
N_CELLS = D.N_CELLS
REGISTERS = D.REGISTERS
RESULTS = D.RESULTS
RESULT_NAMES = {v: k for k, v in D.RESULTS.items()}
FRAMES = D.FRAMES
CELL_FLAGS = D.CELL_FLAGS
_FMT = {"u8": "B", "i8": "b", "u16": "H", "i16": "h", "u32": "I", "i32": "i", "b7": "7s"}


# The rig's one cell -> address mapping lives in tools/flash/addresses.py (the
# flashing tool bakes it into each cell image); the wire definition's ADDR_BASE and
# N_CELLS are checked against it by tests/firmware/test_bus_proto.py.
from tools.flash.addresses import address_cell as cell_of_address  # noqa: E402,F401
from tools.flash.addresses import cell_address  # noqa: E402,F401


def crc8(data: bytes, crc: int = D.CRC8_INIT) -> int:
    """Bitwise reference CRC-8 (poly D.CRC8_POLY, MSB first): independent of the C table."""
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ D.CRC8_POLY) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def layout(fields: list) -> tuple[str, list[str]]:
    """struct format (little-endian) and field names of a block/payload/signal list."""
    return "<" + "".join(_FMT[f[1]] for f in fields), [f[0] for f in fields]


def pack_payload(reg: str, **values: int) -> bytes:
    r = REGISTERS[reg]
    fmt, names = layout(r["payload"])
    missing = set(names) - set(values)
    extra = set(values) - set(names)
    if missing or extra:
        raise ValueError(f"register {reg}: payload fields are {names}, got {sorted(values)}")
    try:
        return struct.pack(fmt, *(values[n] for n in names))
    except struct.error as e:
        raise ValueError(f"register {reg}: {e}") from None


def i2c_write_frame(j: int, reg: str, seq: int, payload: bytes) -> bytes:
    """Bytes of an I2C register write to cell j: reg seq payload crc (CRC also covers addr<<1)."""
    body = bytes([REGISTERS[reg]["id"], seq & 0xFF]) + payload
    return body + bytes([crc8(bytes([cell_address(j) << 1]) + body)])


def decode_block(name: str, data: bytes) -> dict:
    fmt, names = layout(D.BLOCKS[name]["fields"])
    return dict(zip(names, struct.unpack(fmt, data)))


def cmd_frame_id(j: int) -> int:
    cell_address(j)  # validates j
    return FRAMES["CMD"]["base"] + j


def cmd_data(reg: str, seq: int, **values: int) -> bytes:
    """CAN CMD payload: reg, seq, register payload (DLC = 2 + payload length)."""
    if reg not in REGISTERS:
        raise ValueError(f"unknown command register {reg!r}; one of {sorted(REGISTERS)}")
    return bytes([REGISTERS[reg]["id"], seq & 0xFF]) + pack_payload(reg, **values)


@functools.lru_cache(maxsize=1)
def database() -> Any:  # a cantools Database; its decode results are typed as a union of message shapes
    """The shipped CAN database (cantools)."""
    import cantools

    return cantools.database.load_file(str(DBC_PATH))


def reassemble_blocks(chunks: Iterable[bytes]) -> dict:
    """{block name: decoded dict} from BLOCK_DATA payloads of one cell (CRC checked here too)."""
    parts: dict[int, dict[int, bytes]] = {}
    for d in chunks:
        parts.setdefault(d[0] >> 4, {})[d[0] & 15] = bytes(d[1:8])
    names = {b["id"]: k for k, b in D.BLOCKS.items()}
    out = {}
    for blk, p in parts.items():
        if blk not in names:
            continue
        name = names[blk]
        n = sum(D.TYPE_SIZES[f[1]] for f in D.BLOCKS[name]["fields"])
        raw = b"".join(p[k] for k in sorted(p))[:n]
        if len(raw) == n and crc8(raw[:-1]) == raw[-1]:
            out[name] = decode_block(name, raw)
    return out


def map_id() -> int:
    """MC_PROTO_MAP_ID of this definition (what the cells' IDENT block must report)."""
    gen = _load("metacell_protocol_generate", PROTOCOL_DIR / "generate.py")
    return gen.map_id(D)


def frame_kind(arbitration_id: int) -> tuple[str, int | None]:
    """(frame name, cell number or None) of a CAN id, ('UNKNOWN', None) otherwise."""
    for name, f in FRAMES.items():
        if f["per_cell"]:
            j = arbitration_id - f["base"]
            if 1 <= j <= N_CELLS:
                return name, j
        elif arbitration_id == f["base"]:
            return name, None
    return "UNKNOWN", None
