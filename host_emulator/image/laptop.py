"""The laptop on the primary's USB port in the image tier: SLCAN text over the emulated CDC, commands and frames.

It does what the rig's tools do through python-can's slcan interface, in simulated time: the port opened (DTR,
then what python-can's ``slcanBus(bitrate=500000)`` writes: ``C``, ``S6``, an empty line, ``O``, and ``O`` again),
command frames to cells, their results and the primary's frames read back and decoded with the project's CAN
database. The text of a frame is the Lawicel form python-can writes (``tIIILDD..\\r``);
tests/host_emulator/image/test_laptop.py compares all of it with python-can's own slcan interface.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from protocol import wire

from .world import World

# python-can 4.6's slcanBus(bitrate=500000): set_bitrate closes, sets 500 kbit/s and the (empty) data bit rate, opens;
# then the constructor opens once more. shutdown() closes.
OPEN_SEQUENCE = b"C\rS6\r\rO\rO\r"
CLOSE_SEQUENCE = b"C\r"
RETRY_RESULTS = ("BUSY", "NO_ROOM")
# CAN id -> (frame name, cell or None), from the one frame definition
FRAME_OF_ID: dict[int, tuple[str, int | None]] = {
    (f["base"] + (j if f["per_cell"] else 0)): (name, j if f["per_cell"] else None)
    for name, f in wire.FRAMES.items()
    for j in (range(1, wire.N_CELLS + 1) if f["per_cell"] else [0])
}


class LaptopError(RuntimeError):
    """The laptop-side script could not do what it needed (USB not enumerated, a cell refused a command)."""


def encode_frame(arbitration_id: int, data: bytes) -> bytes:
    """The SLCAN text of a standard (11-bit) data frame."""
    if not 0 <= arbitration_id <= 0x7FF or len(data) > 8:
        raise ValueError(f"frame 0x{arbitration_id:x} with {len(data)} bytes: not a standard CAN data frame")
    return f"t{arbitration_id:03X}{len(data)}{data.hex().upper()}\r".encode()


# a data frame line without its CR: t<3 hex id><dlc 0..8><2*dlc hex>, or T<8 hex id>..., then optionally the
# 4-hex-digit Lawicel timestamp (Z1)
_FRAME_LINE = re.compile(rb"(?:t([0-9A-Fa-f]{3})|T([0-9A-Fa-f]{8}))([0-8])([0-9A-Fa-f]*)")


def decode_line(line: bytes) -> tuple[int, bytes] | None:
    """(id, data) of one SLCAN data frame line (``t``/``T``, without its CR), None for anything else (replies,
    errors, remote frames, and malformed lines: an id beyond 11/29 bits, a DLC over 8, data of another length)."""
    m = _FRAME_LINE.fullmatch(line)
    if m is None:
        return None
    std = m.group(1) is not None
    ident, n, data = int(m.group(1) if std else m.group(2), 16), int(m.group(3)), m.group(4)
    if ident > (0x7FF if std else 0x1FFF_FFFF) or len(data) not in (2 * n, 2 * n + 4):
        return None
    return ident, bytes.fromhex(data[: 2 * n].decode())


@dataclass
class Received:
    """What the laptop has read: counts, command results, and the last frame of each kind decoded on demand."""

    samples: int = 0
    frames: dict[str, int] = field(default_factory=dict)
    results: list[tuple[int, int, int, int, int]] = field(default_factory=list)  # (cell, reg, seq, result, retries)
    last: dict[int, bytes] = field(default_factory=dict)  # CAN id -> data of its last frame
    db: object = field(default=None, repr=False)

    def decoded(self, ident: int) -> dict:
        """The last frame with this id, decoded with the project's CAN database ({} when none came)."""
        data = self.last.get(ident)
        if data is None or self.db is None:
            return {}
        return dict(self.db.decode_message(ident, data, decode_choices=False))  # type: ignore[attr-defined]

    def sample(self, cell: int) -> dict:
        return self.decoded(wire.FRAMES["CELL_SAMPLE"]["base"] + cell)

    def status(self, cell: int) -> dict:
        return self.decoded(wire.FRAMES["CELL_STATUS"]["base"] + cell)

    def link(self, cell: int) -> dict:
        return self.decoded(wire.FRAMES["CELL_LINK"]["base"] + cell)

    def health(self) -> dict:
        return self.decoded(wire.FRAMES["PRIMARY_HEALTH"]["base"])

    def primary_status(self) -> dict:
        return self.decoded(wire.FRAMES["PRIMARY_STATUS"]["base"])


class Laptop:
    """A scripted laptop on the world's primary (World.primary)."""

    def __init__(self, world: World, poll_s: float = 0.002) -> None:
        if world.primary is None:
            raise LaptopError("the world has no primary board")
        self.w = world
        self.port = world.primary.index
        self.poll_s = poll_s
        self.seq = 0
        self.rx = Received(db=wire.database())
        self._buf = b""
        self.chunks: dict[int, list[bytes]] = {}  # cell -> BLOCK_DATA payloads since the last read_blocks
        self.raw = bytearray()  # every byte the primary sent while recording
        self.record = False

    # ---- the port --------------------------------------------------------------
    def plug(self, timeout_s: float = 5.0) -> float:
        """Plug the primary's USB cable in and run until the laptop has enumerated it; the world time then."""
        self.w.usb_attach(self.port)
        end = self.w.t + timeout_s
        while self.w.t < end:
            self.w.run_to(self.w.t + 0.01)
            if self.w.usb_info(self.port).configured:
                return self.w.t
        raise LaptopError(f"the primary was not enumerated on USB within {timeout_s} s of plugging it in")

    def open(self) -> None:
        """Open the port as python-can's slcan interface does (DTR up, then its open sequence)."""
        self.w.usb_dtr(self.port, True)
        self.w.run_to(self.w.t + 0.005)
        self.w.usb_write(self.port, OPEN_SEQUENCE)
        self.pump(0.005)

    def close(self) -> None:
        self.w.usb_write(self.port, CLOSE_SEQUENCE)
        self.pump(0.005)
        self.w.usb_dtr(self.port, False)

    # ---- traffic ---------------------------------------------------------------
    def pump(self, seconds: float) -> None:
        """Run the world for `seconds`, reading the port every poll_s (a laptop that keeps up)."""
        end = self.w.t + seconds
        while self.w.t < end - 1e-12:
            self.w.run_to(min(end, self.w.t + self.poll_s))
            self.read()

    def read(self) -> list[tuple[int, bytes]]:
        data = self.w.usb_read(self.port)
        if self.record:
            self.raw += data
        self._buf += data
        frames = []
        while True:
            cut = min((i for i in (self._buf.find(b"\r"), self._buf.find(b"\a")) if i >= 0), default=-1)
            if cut < 0:
                break
            line, self._buf = self._buf[:cut], self._buf[cut + 1 :]
            f = decode_line(line)
            if f:
                frames.append(f)
                self._account(*f)
        return frames

    def _account(self, ident: int, data: bytes) -> None:
        name, cell = FRAME_OF_ID.get(ident, ("UNKNOWN", None))
        self.rx.frames[name] = self.rx.frames.get(name, 0) + 1
        if name == "CELL_SAMPLE":
            self.rx.samples += 1
            self.rx.last[ident] = data
        elif name == "CMD_RESULT" and cell is not None and len(data) >= 4:
            self.rx.results.append((cell, data[0], data[1], data[2], data[3]))
        elif name == "BLOCK_DATA" and cell is not None:
            self.chunks.setdefault(cell, []).append(data)
        else:
            self.rx.last[ident] = data

    def send(self, ident: int, data: bytes) -> None:
        self.w.usb_write(self.port, encode_frame(ident, data))

    # ---- commands --------------------------------------------------------------
    def read_blocks(self, cells: list[int], names: tuple[str, ...] = ("BOOT",), timeout_s: float = 2.0) -> dict:
        """{cell: {block name: decoded dict}} read as the command tool's `info` reads them: a POINTER command per
        block, the primary relays the block as BLOCK_DATA frames (CRC checked on both sides)."""
        self.chunks = {}
        for name in names:
            self.command(cells, "POINTER", timeout_s, block=wire.D.BLOCKS[name]["id"])
        self.pump(0.01)  # the last block's frames follow its result
        return {j: wire.reassemble_blocks(self.chunks.get(j, [])) for j in cells}

    def command(self, cells: list[int], reg: str, timeout_s: float = 2.0, **values: int) -> dict[int, str]:
        """Send reg to every cell and wait for each result (a BUSY or NO_ROOM result is sent again); {cell:
        result name}. LaptopError when a cell gives no result in time."""
        names = wire.RESULT_NAMES
        todo = list(cells)
        out: dict[int, str] = {}
        end = self.w.t + timeout_s
        while todo:
            if self.w.t >= end:
                raise LaptopError(f"{reg}: no result from cell(s) {todo} within {timeout_s} s")
            pending = {}
            for j in todo:
                self.seq = (self.seq + 1) & 0xFF
                pending[j] = self.seq
                self.send(wire.cmd_frame_id(j), wire.cmd_data(reg, self.seq, **values))
            reg_id = wire.REGISTERS[reg]["id"]
            while pending and self.w.t < end:
                self.pump(self.poll_s)
                for cell, r, seq, res, _ in self.rx.results:
                    if pending.get(cell) == seq and r == reg_id:
                        del pending[cell]
                        out[cell] = names.get(res, f"0x{res:02x}")
                self.rx.results.clear()
            todo = [j for j in todo if out.get(j) in RETRY_RESULTS or j in pending]
            for j in todo:
                out.pop(j, None)
        return out
