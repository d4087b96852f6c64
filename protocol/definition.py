"""The single definition of every wire format of the rig: I2C register map and blocks, CAN (SLCAN) frames.

Pure data (Python literals), no imports from the project. ``python -m protocol.generate``
turns it into ``lib/metacell/src/bus/mc_proto.h`` and ``lib/metacell/src/mc_units.h`` (C),
``protocol/metacell.dbc`` (CAN database) and ``docs/datapath-map.md``; the Python side reads
it through ``protocol.wire`` (frames, CRC, addresses) and ``protocol.codec`` (SI <-> register
units). Change the map here, bump PROTO_VERSION when a layout changes, and regenerate;
``tests/firmware/test_bus_proto.py`` fails while the generated files are stale.

All multi-byte fields are little-endian. Types: u8 i8 u16 i16 u32 i32.
"""

import math as _math
from typing import NotRequired, TypedDict


# Shapes of the tables below (for the type checker; the tables stay plain dict and tuple literals).
class Block(TypedDict):
    id: int
    doc: str
    fields: list[tuple[str, str, str]]  # (name, type, description)


class Unit(TypedDict):
    si: str
    micro: NotRequired[int]
    lsb: NotRequired[float]
    text: NotRequired[str]


class Register(TypedDict):
    id: int
    payload: list[tuple[str, str, str | None]]  # (name, type, unit key of UNITS or None)
    range: NotRequired[dict[str, tuple[int, int]]]
    doc: str


class Frame(TypedDict):
    base: int
    per_cell: bool
    sender: str
    dlc: int | None
    doc: str
    signals: NotRequired[list[tuple[str, str, float, float, str, str]]]  # (name, type, scale, offset, unit, text)
    multiplexed: NotRequired[bool]


PROTO_VERSION = 1

# ---------------------------------------------------------------------------
# Addressing: cell j answers at 7-bit address ADDR_BASE + j - 1. The rig as built has N_CELLS cells (0x10..0x1F);
# a sheet may have up to MAX_CELLS (0x10..0x4F), still clear of the reserved ranges 0x00-0x07 and 0x78-0x7F. The
# primary polls the cells its build names (N_CELLS unless told otherwise); every per-cell CAN id below exists for
# 1..MAX_CELLS (the per-cell bases are 0x80 apart, so up to 127 cells never collide). MAX_CELLS is not in the map
# id: no layout depends on it, and a 16-cell rig speaks exactly the frames it spoke before sheets.
N_CELLS = 16
MAX_CELLS = 64
ADDR_BASE = 0x10

# ---------------------------------------------------------------------------
# CRC-8 on every I2C write and on every read block: polynomial x^8+x^2+x+1
# (0x07), initial value 0x00, no reflection, no final xor (SMBus PEC). The CRC of
# a write also covers the address byte (addr << 1, R/W bit 0), so a write that
# reaches the wrong cell is rejected; the CRC of a read block covers its bytes,
# which start with a tag byte and the cell address.
CRC8_POLY = 0x07
CRC8_INIT = 0x00

# ---------------------------------------------------------------------------
# I2C transactions (see docs/datapath.md):
#   write:  S addr+W  reg seq payload[len(reg)] crc8  P      (always ended by STOP)
#   read:   S addr+R  block[...] crc8                P      (separate transaction)
# A read returns the block the read pointer selects (snapshot by default); the
# pointer returns to the snapshot after every read. No repeated start is used.
#
# Read blocks. Byte 0 of every block is its tag = (PROTO_VERSION << 4) | block id,
# byte 1 the cell address; the last byte is CRC-8 of all bytes before it.
BLOCKS: dict[str, Block] = {
    "SNAPSHOT": {
        "id": 0,
        "doc": "one consistent sample taken at a single control tick",
        "fields": [
            ("tag", "u8", "(PROTO_VERSION << 4) | block id"),
            ("addr", "u8", "7-bit address of the cell"),
            ("tick", "u32", "control ticks since the cell booted"),
            ("alpha", "i16", "alpha angle, encoder counts, zeroed, clamped to +-2048"),
            ("beta", "i16", "beta angle, encoder counts, zeroed, clamped to +-2048"),
            ("faults", "u16", "latched MC_FAULT_* flags"),
            ("flags", "u8", "CELL_FLAGS bits"),
            ("cmd_seq", "u8", "sequence byte of the last write processed (0 = none yet)"),
            ("cmd_result", "u8", "RESULT code of that write"),
            ("rejected", "u8", "writes rejected since boot (wraps at 256)"),
            ("dec_err_a", "u16", "illegal quadrature transitions, alpha (wraps)"),
            ("dec_err_b", "u16", "illegal quadrature transitions, beta (wraps)"),
            ("bus_err", "u16", "bad or dropped I2C writes seen by the cell (wraps)"),
            ("crc", "u8", "CRC-8 of all bytes before"),
        ],
    },
    "IDENT": {
        "id": 1,
        "doc": "identity: protocol, address, firmware version and build",
        "fields": [
            ("tag", "u8", "(PROTO_VERSION << 4) | block id"),
            ("addr", "u8", "7-bit address of the cell"),
            ("fw_version", "u16", "MC_FW_VERSION, major << 8 | minor"),
            ("build", "u32", "build identifier given by the glue (e.g. git hash prefix)"),
            ("map_id", "u16", "MC_PROTO_MAP_ID: CRC-16 of this definition's layouts"),
            ("crc", "u8", "CRC-8 of all bytes before"),
        ],
    },
    "PARAMS": {
        "id": 2,
        "doc": "parameters in force (the last accepted values)",
        "fields": [
            ("tag", "u8", "(PROTO_VERSION << 4) | block id"),
            ("addr", "u8", "7-bit address of the cell"),
            ("k_ab", "i32", "uN*m/rad"),
            ("sigma", "i32", "uN*m/rad"),
            ("k1", "i32", "uN*m/rad"),
            ("k2", "i32", "uN*m/rad"),
            ("astar", "i32", "urad"),
            ("pwm_limit", "u16", "PWM limit in force, timer ticks"),
            ("crc", "u8", "CRC-8 of all bytes before"),
        ],
    },
    # --- health additions (firmware review: watchdog and reset cause); additive, no layout above changed ---
    "BOOT": {
        "id": 3,
        "doc": "why the cell last restarted, the watchdog in force and the fault that reset it",
        "fields": [
            ("tag", "u8", "(PROTO_VERSION << 4) | block id"),
            ("addr", "u8", "7-bit address of the cell"),
            ("reset_cause", "u8", "RESET_CAUSE bits read at boot (SAMD21 PM RCAUSE)"),
            ("wdt_ms", "u16", "watchdog timeout in force, ms (0 = off)"),
            # --- fault record (firmware review: fault handlers); additive at the end ---
            (
                "fault_exc",
                "u8",
                "exception that reset the cell through its fault handler (3 HardFault, 11 SVCall, 14 PendSV, "
                "16+n interrupt n); 0 = none",
            ),
            ("fault_pc", "u32", "address the fault interrupted (stacked PC); 0 = none"),
            ("crc", "u8", "CRC-8 of all bytes before"),
        ],
    },
}

# Reset cause bits (BOOT.reset_cause, PRIMARY_HEALTH.reset_cause): the SAMD21 PM RCAUSE register as read at boot.
RESET_CAUSE = {
    "POR": 0,  # power-on reset
    "BOD12": 1,  # 1.2 V brown-out
    "BOD33": 2,  # 3.3 V brown-out
    "EXT": 4,  # reset pin
    "WDT": 5,  # watchdog expired (the firmware hung)
    "SYST": 6,  # system reset request (software reset, bootloader entry)
    # not an RCAUSE bit (bit 7 is reserved there): the firmware's fault handler (HardFault or an interrupt
    # nobody handles) put the drivers to sleep and requested the reset; SYST is set with it
    "FAULT": 7,
}

CELL_FLAGS = {
    "ENABLED": 0,  # drive enable requested
    "BEMF": 1,  # back-EMF compensation on
    "PERTURBING": 2,  # a perturbation is running
    "PENDING": 3,  # a write waits for the next tick boundary
    "FAULT": 4,  # faults != 0 (drivers off)
}

# ---------------------------------------------------------------------------
# Physical units and the firmware's acceptance limits. Each register field and frame signal names its unit (a
# key of UNITS); protocol/codec.py converts SI <-> register values with them, the generator writes them into
# lib/metacell/src/mc_units.h (the C library's own constants) and into the DBC's physical view. One line here
# changes every side.
COUNTS_PER_REV = 400  # encoder counts per revolution: angles on the wire and in the firmware
TORQUE_WIRE_UNM = 4  # PERTURB torque on the wire: one LSB = 4 uN*m (so an i16 spans +-131 mN*m)

# Limits in register units (uN*m/rad, urad, uN*m); the cell library rejects anything outside (RESULT RANGE).
LIMITS = {
    "K_MAX_UNM": 250000,  # |k_ab|, |sigma|, |k1|, |k2| <= 0.25 N*m/rad
    "ASTAR_MAX_URAD": 6283185,  # 0 <= alpha* <= 2 pi rad
    "PERTURB_MAX_UNM": 131000,  # |perturbing torque| <= 0.131 N*m (within the 2^22 TU torque clamp)
}

# unit -> {"si": SI unit, and either "micro": LSB in millionths of the SI unit (the codec computes
# round(x * 1e6 / micro), exact for micro = 1) or "lsb": SI value of one LSB; "text": how docs name it}.
UNITS: dict[str, Unit] = {
    "uN*m/rad": {"si": "N*m/rad", "micro": 1},
    "urad": {"si": "rad", "micro": 1},
    "uN*m": {"si": "N*m", "micro": 1},
    "wire torque": {"si": "N*m", "micro": TORQUE_WIRE_UNM, "text": f"{TORQUE_WIRE_UNM} uN*m"},
    "count": {"si": "rad", "lsb": 2 * _math.pi / COUNTS_PER_REV, "text": f"count, {COUNTS_PER_REV}/rev"},
    "tick": {"si": "tick", "lsb": 1, "text": "control ticks"},
    "timer tick": {"si": "timer tick", "lsb": 1, "text": "timer ticks"},
}

# Writable registers. Payloads are the same bytes in the I2C write and in the
# CAN command frame (after reg and seq), so one layout serves both.
# Payload fields: (name, type, unit key of UNITS or None). "range": {field: (lo, hi)} in register units, the
# firmware's acceptance range, used by protocol/codec.py to refuse a value before it is sent; the cell library
# checks the same LIMITS and rejects anything else (RESULT RANGE/SHAPE/CONFIG).
_K = LIMITS["K_MAX_UNM"]
_T = LIMITS["PERTURB_MAX_UNM"] // TORQUE_WIRE_UNM  # largest |torque| on the wire the cell accepts
REGISTERS: dict[str, Register] = {
    "POINTER": {
        "id": 0x01,
        "payload": [("block", "u8", None)],
        "doc": "select the block returned by the next read (SNAPSHOT after it); applied at once. "
        "As a CAN CMD: the primary reads that block and sends it as BLOCK_DATA frames",
    },
    "K_AB": {"id": 0x10, "payload": [("value", "i32", "uN*m/rad")], "range": {"value": (-_K, _K)}, "doc": "k_ab"},
    "SIGMA": {"id": 0x11, "payload": [("value", "i32", "uN*m/rad")], "range": {"value": (-_K, _K)}, "doc": "sigma"},
    "K1": {
        "id": 0x12,
        "payload": [("value", "i32", "uN*m/rad")],
        "range": {"value": (-_K, _K)},
        "doc": "k1 (> 0, > k2)",
    },
    "K2": {"id": 0x13, "payload": [("value", "i32", "uN*m/rad")], "range": {"value": (-_K, _K)}, "doc": "k2 (< k1)"},
    "ASTAR": {
        "id": 0x14,
        "payload": [("value", "i32", "urad")],
        "range": {"value": (0, LIMITS["ASTAR_MAX_URAD"])},
        "doc": "alpha*",
    },
    "ENABLE": {"id": 0x20, "payload": [("on", "u8", None)], "range": {"on": (0, 1)}, "doc": "drive enable"},
    "BEMF": {
        "id": 0x21,
        "payload": [("on", "u8", None)],
        "range": {"on": (0, 1)},
        "doc": "back-EMF compensation",
    },
    "PERTURB": {
        "id": 0x22,
        "payload": [("chain", "u8", None), ("torque", "i16", "wire torque"), ("ticks", "u16", "tick")],
        "range": {"chain": (0, 1), "torque": (-_T, _T)},
        "doc": "perturbing torque on chain 0=alpha 1=beta for ticks control ticks",
    },
    "ZERO": {"id": 0x23, "payload": [], "doc": "make the current positions the zero of both angles"},
    "PWM_LIMIT": {
        "id": 0x24,
        "payload": [("ticks", "u16", "timer tick")],
        "doc": "PWM duty limit (clamped to the 5.86 V cap)",
    },
    "CLEAR_FAULTS": {"id": 0x25, "payload": [], "doc": "clear latched faults"},
}

# Results (snapshot cmd_result, CAN CMD_RESULT.result). Codes >= 0x10 come from
# the primary, not from the cell.
RESULTS = {
    "NONE": 0x00,  # no write processed yet
    "OK": 0x01,
    "RANGE": 0x02,  # value outside its range (library MC_ERR_RANGE)
    "SHAPE": 0x03,  # k1 <= k2 or k1 <= 0 (MC_ERR_SHAPE)
    "CONFIG": 0x04,  # drive configuration refused (MC_ERR_CONFIG)
    "LENGTH": 0x05,  # frame length does not match the register
    "CRC": 0x06,  # CRC-8 mismatch
    "REG": 0x07,  # unknown register
    "NACK": 0x10,  # cell did not acknowledge the write (after retries)
    "TIMEOUT": 0x11,  # no acknowledgement in the cell's snapshot in time
    "BUSY": 0x12,  # a command to this cell is still in flight
    "NO_CELL": 0x13,  # cell number outside the cells the primary polls (1..N_CELLS unless built for more)
    "BAD_FRAME": 0x14,  # CAN command frame malformed (dlc, reg)
    "NO_ROOM": 0x15,  # the primary's outgoing queue had no room to take the command (resend later)
}

# ---------------------------------------------------------------------------
# CAN frames on the SLCAN link (11-bit ids). "{j}" frames exist per cell j=1..MAX_CELLS
# at base + j. Signals: (name, type, scale, offset, unit, comment).
# Signals are packed little-endian in order, starting at byte 0.
FRAMES: dict[str, Frame] = {
    "CELL_SAMPLE": {
        "base": 0x100,
        "per_cell": True,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "one snapshot of cell j, sent for every successful poll",
        "signals": [
            ("seq", "u8", 1, 0, "", "per-cell sample counter (wraps at 256): gaps = lost samples"),
            ("alpha", "i16", 1, 0, "count", "alpha angle, encoder counts"),
            ("beta", "i16", 1, 0, "count", "beta angle, encoder counts"),
            ("t128", "u16", 128e-6, 0, "s", "primary clock at the read, 128 us units (wraps)"),
            ("flags", "u8", 1, 0, "", "CELL_FLAGS bits"),
        ],
    },
    "CELL_STATUS": {
        "base": 0x200,
        "per_cell": True,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "cell-side status of cell j (every STATUS_EVERY cycles and on change)",
        "signals": [
            ("faults", "u16", 1, 0, "", "latched MC_FAULT_* flags"),
            ("tick_lo", "u16", 1, 0, "tick", "cell control tick, low 16 bits"),
            ("rejected", "u8", 1, 0, "", "writes rejected by the cell (wraps)"),
            ("dec_err_a", "u8", 1, 0, "", "alpha decoder errors, low 8 bits"),
            ("dec_err_b", "u8", 1, 0, "", "beta decoder errors, low 8 bits"),
            ("bus_err", "u8", 1, 0, "", "cell-side bus errors, low 8 bits"),
        ],
    },
    "CELL_LINK": {
        "base": 0x280,
        "per_cell": True,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "primary-side link counters of cell j (every STATUS_EVERY cycles)",
        "signals": [
            ("nack", "u16", 1, 0, "", "address/data NACKs (wraps)"),
            ("integrity", "u16", 1, 0, "", "bad tag, address or CRC in read blocks (wraps)"),
            ("timeout", "u16", 1, 0, "", "transactions that hit their timeout (wraps)"),
            ("skipped", "u16", 1, 0, "", "polls skipped by back-off (wraps)"),
        ],
    },
    "CMD": {
        "base": 0x300,
        "per_cell": True,
        "sender": "LAPTOP",
        "dlc": None,
        "doc": "command to cell j: reg, seq, payload of REGISTERS[reg] (dlc = 2 + payload)",
        "multiplexed": True,
    },
    "CMD_RESULT": {
        "base": 0x380,
        "per_cell": True,
        "sender": "PRIMARY",
        "dlc": 4,
        "doc": "result of a CMD to cell j",
        "signals": [
            ("reg", "u8", 1, 0, "", "register of the command"),
            ("seq", "u8", 1, 0, "", "seq of the command as sent by the laptop"),
            ("result", "u8", 1, 0, "", "RESULTS code"),
            ("retries", "u8", 1, 0, "", "I2C write retries used"),
        ],
    },
    "BLOCK_DATA": {
        "base": 0x400,
        "per_cell": True,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "a read block of cell j (CMD reg POINTER), in 7-byte chunks, CRC-checked by the primary",
        "signals": [
            ("part", "u8", 1, 0, "", "(block id << 4) | chunk index; chunk k holds block bytes 7k..7k+6"),
            ("chunk", "b7", 1, 0, "", "block bytes (zero-padded after the block's end)"),
        ],
    },
    "PRIMARY_STATUS": {
        "base": 0x0F0,
        "per_cell": False,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "primary heartbeat, once per second",
        "signals": [
            ("uptime_ms", "u32", 1e-3, 0, "s", "primary clock (wraps after 49.7 days)"),
            ("cycles", "u16", 1, 0, "", "full polling cycles in the last second"),
            ("slcan_err", "u8", 1, 0, "", "malformed SLCAN lines (wraps)"),
            ("tx_drop", "u8", 1, 0, "", "data frames dropped because the USB queue was full (saturates at 255)"),
        ],
    },
    "PRIMARY_REJECT": {
        "base": 0x0F1,
        "per_cell": False,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "a frame from the laptop was rejected by the primary",
        "signals": [
            ("reason", "u8", 1, 0, "", "RESULTS code (BAD_FRAME, NO_CELL, ...)"),
            ("bad_id", "u32", 1, 0, "", "CAN id of the rejected frame (bit 31: extended)"),
            ("bad_dlc", "u8", 1, 0, "", "its DLC"),
            ("count", "u16", 1, 0, "", "rejected frames since boot (wraps)"),
        ],
    },
    # --- health addition (firmware review: USB flow control, bus recovery, reset cause); additive ---
    "PRIMARY_HEALTH": {
        "base": 0x0F2,
        "per_cell": False,
        "sender": "PRIMARY",
        "dlc": 8,
        "doc": "primary health, once per second after the heartbeat",
        "signals": [
            ("reset_cause", "u8", 1, 0, "", "RESET_CAUSE bits read at the primary's boot"),
            ("usb_lost", "u32", 1, 0, "byte", "SLCAN output bytes the USB port did not take (saturates)"),
            ("bus_reset", "u16", 1, 0, "", "I2C bus recoveries: 9 clocks and a STOP (wraps)"),
            ("usb_fail", "u8", 1, 0, "", "USB writes that failed (wraps)"),
        ],
    },
}

# ---------------------------------------------------------------------------
# Primary schedule defaults (configurable at run time; documented here so the C
# and Python sides agree).
SCHEDULE = {
    "I2C_HZ": 400000,  # bus clock
    "STATUS_EVERY": 64,  # cycles between CELL_STATUS/CELL_LINK frames per cell
    "TXN_TIMEOUT_US": 2000,  # per-transaction timeout
    "ACK_TIMEOUT_US": 50000,  # command acknowledgement timeout
    "WRITE_RETRIES": 2,  # extra attempts of a NACKed write
    "BACKOFF_MAX": 64,  # cycles a repeatedly timing-out cell is skipped (max)
}

TYPE_SIZES = {"u8": 1, "i8": 1, "u16": 2, "i16": 2, "u32": 4, "i32": 4, "b7": 7}  # b7: 7 raw bytes

# ---------------------------------------------------------------------------
# The CAN database's physical view (protocol/metacell.dbc only: the wire layout, the C header and the map id do
# not depend on it). Tools that read the DBC (cantools decode/monitor, SavvyCAN, ...) show SI units and names;
# code that wants the raw wire integers decodes with scaling=False, decode_choices=False. Every register field and
# frame signal whose unit is in UNITS is shown in its SI unit; DBC_PHYSICAL overrides single signals
# ((frame, signal) -> (scale, offset, unit); "CMD" signals are named <REGISTER>_<field>).
DBC_PHYSICAL: dict[tuple[str, str], tuple[float, float, str]] = {}

# (frame, signal) -> {raw value: name}: value tables of the enumerations. CELL_SAMPLE.flags is a bit field:
# its table names the single-bit values (a combination decodes as its number).
_REG_NAMES = {r["id"]: name for name, r in REGISTERS.items()}
_RESULT_NAMES = {v: k for k, v in RESULTS.items()}
DBC_CHOICES = {
    ("CMD", "reg"): _REG_NAMES,
    ("CMD_RESULT", "reg"): _REG_NAMES,
    ("CMD_RESULT", "result"): _RESULT_NAMES,
    ("PRIMARY_REJECT", "reason"): _RESULT_NAMES,
    ("CELL_SAMPLE", "flags"): {0: "NONE", **{1 << b: name for name, b in CELL_FLAGS.items()}},
    ("CMD", "PERTURB_chain"): {0: "ALPHA", 1: "BETA"},
    ("CMD", "ENABLE_on"): {0: "OFF", 1: "ON"},
    ("CMD", "BEMF_on"): {0: "OFF", 1: "ON"},
}

# frame -> cycle time in ms (frames sent on a fixed period; the per-cell frames follow the polling rate).
DBC_CYCLE_MS = {"PRIMARY_STATUS": 1000, "PRIMARY_HEALTH": 1000}
