"""Parse (and query) the board identity line `MC role=... addr=... cell=... fw=...` (src/common/mc_ident.h)."""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import serial

from .addresses import MAX_CELL_COUNT, RESERVED

ROOT = Path(__file__).resolve().parents[2]
REQUEST = b"ID?\r\n"
SAFE_BAUD = 115200  # USB CDC ignores it; 1200 would reset the XIAO into its bootloader
ROLES = ("cell", "primary")


class IdentityError(ValueError):
    """A line that claims to be an identity reply but is malformed."""


@dataclass(frozen=True)
class Identity:
    role: str  # "cell" or "primary"
    fw: str  # "major.minor"
    cell: int | None = None  # 0 (unaddressed image) or 1..64 for a cell (1..16 on the rig as built)
    addr: int | None = None  # 7-bit I2C address, None when unaddressed / primary
    extra: tuple = field(default=(), compare=False)  # unknown key=value pairs, kept

    def describe(self) -> str:
        if self.role == "primary":
            return f"primary fw={self.fw}"
        a = "none" if self.addr is None else f"0x{self.addr:02x}"
        return f"cell {self.cell} addr={a} fw={self.fw}"


_NUM = r"(0|[1-9]\d{0,2})"  # decimal, no leading zeros (the C formatter never writes them)
_FW_RE = re.compile(rf"^{_NUM}\.{_NUM}$")
_ADDR_RE = re.compile(r"^0x[0-9a-fA-F]{2}$")
_DEC_RE = re.compile(rf"^{_NUM}$")


def is_identity_line(line: str) -> bool:
    return line.strip().startswith("MC role=")


def parse_identity(line: str) -> Identity:
    """Parse one reply line. Raises IdentityError naming what is wrong."""
    text = line.strip()
    parts = text.split()
    if len(parts) < 2 or parts[0] != "MC":
        raise IdentityError(f"not an identity line: {line!r}")
    kv: dict[str, str] = {}
    for tok in parts[1:]:
        key, sep, val = tok.partition("=")
        if not sep or not key or not val:
            raise IdentityError(f"bad field {tok!r} in {line!r}")
        if key in kv:
            raise IdentityError(f"field {key!r} repeated in {line!r}")
        kv[key] = val
    role = kv.pop("role", None)
    if role not in ROLES:
        raise IdentityError(f"role must be one of {ROLES}, got {role!r} in {line!r}")
    fw = kv.pop("fw", "")
    m = _FW_RE.match(fw)
    if not m or int(m.group(1)) > 255 or int(m.group(2)) > 255:
        raise IdentityError(f"fw must be major.minor (0..255 each), got {fw!r} in {line!r}")
    if role == "primary":
        for key in ("addr", "cell"):
            if key in kv:
                raise IdentityError(f"primary reply carries {key}= in {line!r}")
        return Identity("primary", fw, extra=tuple(sorted(kv.items())))
    addr_s, cell_s = kv.pop("addr", None), kv.pop("cell", None)
    if cell_s is None or not _DEC_RE.match(cell_s) or int(cell_s) > MAX_CELL_COUNT:
        raise IdentityError(f"cell must be 0..{MAX_CELL_COUNT}, got {cell_s!r} in {line!r}")
    cell = int(cell_s)
    if addr_s == "none":
        addr = None
    elif addr_s is not None and _ADDR_RE.match(addr_s):
        addr = int(addr_s, 16)
        if addr in RESERVED or addr > 0x7F:
            raise IdentityError(f"address 0x{addr:02x} is reserved in {line!r}")
    else:
        raise IdentityError(f"addr must be 0xHH or none, got {addr_s!r} in {line!r}")
    if (cell == 0) != (addr is None):
        raise IdentityError(f"cell {cell} with addr={addr_s} is inconsistent in {line!r}")
    return Identity("cell", fw, cell=cell, addr=addr, extra=tuple(sorted(kv.items())))


def expected_fw_version(header: Path | None = None) -> str:
    """major.minor of MC_FW_VERSION in the library header (the one release number)."""
    header = header or ROOT / "lib" / "metacell" / "src" / "mc_cell.h"
    m = re.search(r"^#define\s+MC_FW_VERSION\s+(0x[0-9A-Fa-f]+|\d+)", header.read_text(), re.M)
    if not m:
        raise RuntimeError(f"MC_FW_VERSION not found in {header}")
    v = int(m.group(1), 0)
    return f"{v >> 8}.{v & 0xFF}"


def open_serial(device: str, timeout: float = 0.2) -> serial.Serial:
    """Open a board's USB CDC port for data (never at 1200 baud)."""
    import serial  # pyserial

    return serial.Serial(device, baudrate=SAFE_BAUD, timeout=timeout)


class QueryResult:
    """What a board answered: its identity (or None) and any `MC error=` lines."""

    def __init__(self, identity: Identity | None, errors: list[str], raw: list[str]) -> None:
        self.identity, self.errors, self.raw = identity, errors, raw


def query_identity(
    device: str,
    opener: Callable[..., Any] = open_serial,
    timeout: float = 3.0,
    retry_every: float = 0.5,
    clock: Callable[[], float] = time.monotonic,
) -> QueryResult:
    """Send `ID?` (again every retry_every s) until an identity line arrives or timeout.

    Lines that are not identity replies (e.g. SLCAN traffic of the primary) are kept in
    .raw and otherwise ignored; `MC error=...` lines are collected in .errors. A
    malformed identity line raises IdentityError.
    """
    port = opener(device)
    raw: list[str] = []
    errors: list[str] = []
    try:
        start = clock()
        next_send = start
        buf = b""
        while clock() - start < timeout:
            if clock() >= next_send:
                port.write(REQUEST)
                next_send = clock() + retry_every
            chunk = port.readline()
            if not chunk:
                continue
            buf += chunk
            if not buf.endswith((b"\n", b"\r")):
                continue
            for piece in re.split(rb"[\r\n]+", buf):
                line = piece.decode("ascii", "replace").strip()
                if not line:
                    continue
                raw.append(line)
                if line.startswith("MC error="):
                    errors.append(line[len("MC error=") :])
                elif is_identity_line(line):
                    return QueryResult(parse_identity(line), errors, raw)
            buf = b""
        return QueryResult(None, errors, raw)
    finally:
        port.close()
