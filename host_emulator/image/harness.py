"""Register-level harness of the image tier: boards with no image, their registers reached as their CPU reaches them.

A board runs a stub program instead of a flashed image: a vector table, a reset handler that masks interrupts
(``cpsid i``, unless the program asks otherwise) and idles (``b .``), and one routine per access kind
(``ldr``/``str`` of 1, 2 or 4 bytes, then ``b .``). ``Harness.write``/``read`` run such a routine on the board's
CPU (Unicorn), so an access goes through the same MMIO dispatch, bus-clock checks, access rules and models as the
firmware's own, at the board's time and with the cycles it costs (csrc/sam_harness.c). ``advance`` runs the world
(timers, PWM, the watchdog, pin events, the I2C bus, the plant's windows); the idle loop is fast-forwarded. Pins
are driven from outside as the encoders drive them; what the plant sees of a cell's drivers is ``motor``.

No firmware, PlatformIO tree or ARM toolchain is needed: the runtime is built from the register table's snapshot
when the vendor's headers are absent (regsnapshot.load_or_snapshot), and the stub is assembled here.

    h = Harness()                       # one cell board, from power-up
    h.write("PM.APBCMASK", h.read("PM.APBCMASK") | 1 << 11)   # TC3's bus clock
    h.write("GCLK.CLKCTRL", 0x1B | 1 << 14)                    # its generic clock from GCLK0 (1 MHz)
    h.write("TC3.COUNT16.CC[0]", 999)
    h.advance(1e-3)
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from metacell_common.target.cycles import Function

from ..models.options import ModelOptions
from ..models.plant import build_plant
from ..params import Params
from . import board as wiring
from . import cycles, regsnapshot, runtime
from .elfimage import APP_BASE
from .world import set_pwm

SRAM_TOP = 0x2000_8000
N_VECTORS = 16 + 32


class HarnessError(RuntimeError):
    """The board stopped: an access the models do not cover (the message names it), or a harness misuse."""


# ---------------------------------------------------------------- a small Thumb assembler (ARMv6-M subset)


class Asm:
    """Thumb code at `base` with labels and a literal pool; `insns` feeds the cycle model (cycles.block_tables)."""

    def __init__(self, base: int) -> None:
        self.base = base
        self.code = bytearray()
        self.insns: list[cycles.Insn] = []
        self.labels: dict[str, int] = {}
        self._fix: list[tuple[int, str, str]] = []  # (offset, kind, label or literal key)
        self._lits: list[int] = []
        self._lit_fix: list[tuple[int, int]] = []  # (offset of the ldr, index in _lits)

    @property
    def here(self) -> int:
        return self.base + len(self.code)

    def label(self, name: str) -> int:
        self.labels[name] = self.here
        return self.here

    def _h(self, hw: int, mnem: str, ops: str = "") -> None:
        self.insns.append(cycles.Insn(self.here, mnem, ops, ""))
        self.code += struct.pack("<H", hw)

    def _w(self, hw1: int, hw2: int, mnem: str, ops: str = "") -> None:
        self.insns.append(cycles.Insn(self.here, mnem, ops, ""))
        self.code += struct.pack("<HH", hw1, hw2)

    def cpsid(self) -> None:
        self._h(0xB672, "cpsid", "i")

    def cpsie(self) -> None:
        self._h(0xB662, "cpsie", "i")

    def b(self, label: str | None = None) -> None:
        """B to a label (None: to itself, `b .`)."""
        self._fix.append((len(self.code), "b", label or f"@{self.here}"))
        self._h(0xE000, "b", label or ".")

    def bcond(self, cond: int, label: str, mnem: str) -> None:
        """B<cond> back to a label already placed (ARMv6-M T1: cond 0 EQ, 2 CS, 3 CC, ...)."""
        here = self.here
        self._h(0xD000 | cond << 8 | ((self.labels[label] - (here + 4)) >> 1) & 0xFF, mnem, label)

    def bx_lr(self) -> None:
        self._h(0x4770, "bx", "lr")

    def nop(self) -> None:
        self._h(0xBF00, "nop")

    def align(self, n: int) -> None:
        """NOPs up to the next multiple of n bytes (code placed on a flash row or page)."""
        while self.here % n:
            self.nop()

    def movs(self, rd: int, imm: int) -> None:
        assert 0 <= imm < 256 and rd < 8
        self._h(0x2000 | rd << 8 | imm, "movs", f"r{rd}, #{imm}")

    def adds(self, rd: int, imm: int) -> None:
        assert 0 <= imm < 256 and rd < 8
        self._h(0x3000 | rd << 8 | imm, "adds", f"r{rd}, #{imm}")

    def mov_from_sp(self, rd: int) -> None:
        self._h(0x4668 | rd, "mov", f"r{rd}, sp")

    def mem(self, op: str, rt: int, rn: int, imm: int = 0) -> None:
        """ldr/str/ldrh/strh/ldrb/strb rt, [rn, #imm]."""
        base, scale = {
            "str": (0x6000, 4),
            "ldr": (0x6800, 4),
            "strb": (0x7000, 1),
            "ldrb": (0x7800, 1),
            "strh": (0x8000, 2),
            "ldrh": (0x8800, 2),
        }[op]
        assert imm % scale == 0 and 0 <= imm // scale < 32 and rt < 8 and rn < 8
        self._h(base | (imm // scale) << 6 | rn << 3 | rt, op, f"r{rt}, [r{rn}, #{imm}]")

    def ldr_const(self, rd: int, value: int) -> None:
        """ldr rd, =value (a PC-relative load from the pool placed by `pool`)."""
        self._lit_fix.append((len(self.code), len(self._lits)))
        self._lits.append(value & 0xFFFFFFFF)
        self._h(0x4800 | rd << 8, "ldr", f"r{rd}, [pc, #0]")

    def dsb_isb(self) -> None:
        """DSB; ISB: the effect of the stores before (an NVIC pend) is recognised before what follows."""
        self._w(0xF3BF, 0x8F4F, "dsb", "sy")
        self._w(0xF3BF, 0x8F6F, "isb", "sy")

    def pool(self) -> None:
        """The literal pool of the ldr_const loads so far (after an unconditional branch or return)."""
        if len(self.code) % 4:
            self.code += b"\x00\x00"
        start = len(self.code)
        for v in self._lits:
            self.code += struct.pack("<I", v)
        for off, k in self._lit_fix:
            pc = (self.base + off + 4) & ~3
            imm = (self.base + start + 4 * k - pc) // 4
            assert 0 <= imm < 256, "literal pool out of reach"
            (hw,) = struct.unpack_from("<H", self.code, off)
            struct.pack_into("<H", self.code, off, hw | imm)
        self._lits, self._lit_fix = [], []

    def finish(self) -> bytes:
        assert not self._lits, "literals without a pool"
        for off, _kind, lab in self._fix:
            target = int(lab[1:]) if lab.startswith("@") else self.labels[lab]
            d = (target - (self.base + off + 4)) >> 1
            assert -1024 <= d < 1024
            struct.pack_into("<H", self.code, off, 0xE000 | (d & 0x7FF))
        return bytes(self.code)


#: the access routines: (load/store mnemonic) by (write, size)
_ROUTINES = {(w, s): ("str" if w else "ldr") + {1: "b", 2: "h", 4: ""}[s] for w in (0, 1) for s in (1, 2, 4)}


@dataclass
class Program:
    """A stub program: the code after the vector table, its handlers (exception number -> label) and labels."""

    code: bytes
    entry: int
    idle: int
    routines: dict[tuple[int, int], int]
    labels: dict[str, int]
    tables: cycles.BlockTables | None  # None: no ELF tables, the board's decoder costs the code (csrc/sam_cost.c)
    vectors: list[int] = field(default_factory=list)
    heap_base: int = 0  # end of its static data in SRAM, as an ELF's `end` gives it (0: unknown, all RAM is data)

    @property
    def image(self) -> bytes:
        return struct.pack(f"<{N_VECTORS}I", *self.vectors) + self.code


def stub(handlers=None, *, irqs_enabled: bool = False) -> Program:
    """The harness's program. `handlers(asm)` may add code and returns {exception number: label}; a handler not
    given is `b .` (a fault or an unexpected interrupt stops there). Interrupts stay masked (PRIMASK) unless
    irqs_enabled: then pending interrupts are taken and must have handlers."""
    a = Asm(APP_BASE + 4 * N_VECTORS)
    a.label("reset")
    a.cpsie() if irqs_enabled else a.cpsid()
    a.label("idle")
    a.b()
    a.label("default")
    a.b()
    routines = {}
    for key, op in _ROUTINES.items():
        routines[key] = a.label(f"{op}_routine")
        a.mem(op, 1, 0)
        a.b()
    own = handlers(a) if handlers else {}
    code = a.finish()
    vectors = [SRAM_TOP, a.labels["reset"] | 1] + [a.labels["default"] | 1] * (N_VECTORS - 2)
    for exc, lab in own.items():
        vectors[exc] = a.labels[lab] | 1
    image = cycles.Image({"stub": Function("stub", a.base, a.insns)}, {a.base: "stub"}, {})
    tables = cycles.block_tables(image)
    return Program(code, a.labels["reset"], a.labels["idle"], routines, dict(a.labels), tables, vectors)


# ---------------------------------------------------------------- the harness


@dataclass
class PinState:
    level: int  # the pad's level
    out: int  # what the MCU puts on it: 0, 1 (GPIO output or pull direction), -1 nothing
    driven: bool  # a GPIO output drives it
    function: int  # PMUX letter 0..7 (A..H) when PINCFG.PMUXEN, else -1


class Harness:
    """Boards ("cell", "primary") with no image in one world, from power-up at time 0. Registers by their table
    name ("TC3.COUNT16.CC[0]") or address; times in tu (`tu_hz` per second) or seconds."""

    def __init__(
        self,
        board: str = "cell",
        *,
        boards: Sequence[str] | None = None,
        program: Program | None = None,
        window_s: float = 100e-6,
        ff: bool = True,
        ff_timed: bool = False,
        built: tuple[Any, Any] | None = None,
        pwm: str = "mean",
        motor_tau_s: float = 0.0,
    ) -> None:
        """`built`: the (ffi, lib) of a runtime from runtime.load (default: the one of image/csrc)."""
        self.ffi, self.lib = ffi, lib = built or runtime.load()
        self.table = regsnapshot.load_or_snapshot()
        self._regs = {r.full: (p.base + r.offset, r.size) for p in self.table.peripherals for r in p.registers}
        self.roles = list(boards or [board])
        ncells = max(1, sum(r == "cell" for r in self.roles))
        self.params = Params(cells=ncells)
        self.options = ModelOptions()
        self.plant = build_plant(ffi, lib, self.params, self.options, ncells, [], ideal_reaction=False)
        self.x, self.v = np.zeros(2 * ncells), np.zeros(2 * ncells)
        self.tu_hz = int(lib.sam_tu_hz())
        c = ffi.new("sam_world_cfg_t *")
        c.ncells, c.primary = ncells, int("primary" in self.roles)
        c.window_s, c.substeps = window_s, 1
        from ..models.steppers import stepper_id

        c.stepper = stepper_id(lib, self.options.stepper)
        c.supply_v, c.kt = self.params.supply_v, self.params.kt
        c.counts_per_rad = lib.MC_COUNTS_PER_REV / (2 * math.pi)
        c.i2c_rise_ns, c.usb_packet_us = 125.0, 50.0
        c.ff, c.cycle_model, c.round_s, c.threads = int(ff), 0, 0.0, 1
        c.ff_timed = int(ff_timed)
        cm = cycles.CycleModel()
        c.cyc_exc_entry, c.cyc_exc_exit, c.cyc_apb = cm.exc_entry, cm.exc_exit, cm.apb_extra
        c.plant = self.plant
        set_pwm(c, pwm, motor_tau_s)
        self._px, self._pv = ffi.from_buffer("double[]", self.x), ffi.from_buffer("double[]", self.v)
        c.x, c.v = self._px, self._pv
        wiring.wire(c)
        self._cfg = c
        wp = ffi.new("sam_world_t **")
        rc = lib.sam_world_new(wp, c)
        self._w = ffi.gc(wp[0], lib.sam_world_free)
        if rc:
            raise HarnessError(ffi.string(lib.sam_world_error(self._w)).decode())
        self.program = program or stub()
        self._keep: list = []
        cell = 0
        for i, role in enumerate(self.roles):
            if role not in ("cell", "primary"):
                raise ValueError(f"board {role!r}: expected 'cell' or 'primary'")
            self._load(i, role, cell if role == "cell" else -1)
            cell += role == "cell"
        self.t_access = 0  # when the last read or write happened (tu)

    def _load(self, idx: int, role: str, cell: int) -> None:
        ffi, lib, p = self.ffi, self.lib, self.program
        data = ffi.new("uint8_t[]", p.image)
        seg = ffi.new("sam_seg_t *")
        seg.addr, seg.len, seg.data = APP_BASE, len(p.image), data
        t = p.tables
        arrays = []
        if t is not None:
            arrays = [ffi.from_buffer(ty, a) for ty, a in (("uint32_t[]", t.core), ("uint32_t[]", t.wait))]
            arrays += [ffi.from_buffer("uint32_t[]", t.literal), ffi.from_buffer("uint8_t[]", t.refund)]
        im = ffi.new("sam_image_t *")
        im.segs, im.nsegs = seg, 1
        im.entry_sp, im.entry_pc = SRAM_TOP, p.entry | 1
        if arrays:
            im.cost_core, im.cost_wait, im.cost_lit, im.refund = arrays
        im.code_end = APP_BASE + len(p.image) if arrays else 0
        im.loop_pc, im.heap_base, im.brk_var = p.idle, p.heap_base, 0
        self._keep += [data, seg, im, t, *arrays]
        name = f"{role} {idx}".encode()
        r = lib.SAM_ROLE_CELL if role == "cell" else lib.SAM_ROLE_PRIMARY
        if lib.sam_world_load(self._w, idx, im, name, r, cell):
            raise HarnessError(ffi.string(lib.sam_world_error(self._w)).decode())

    # ---- registers -------------------------------------------------------------------------------------
    def address(self, reg: str | int, size: int | None = None) -> tuple[int, int]:
        """(address, size) of a register name ("PORT.Group[0].OUTSET") or of an address (size default 4)."""
        if isinstance(reg, int):
            return reg, size or 4
        try:
            addr, rsize = self._regs[reg]
        except KeyError:
            raise KeyError(f"{reg!r}: no such register in the table") from None
        return addr, size or rsize

    def _call(self, write: int, reg: str | int, value: int, size: int | None, board: int) -> int:
        addr, size = self.address(reg, size)
        if size not in (1, 2, 4):
            raise ValueError(f"size {size}: expected 1, 2 or 4")
        pc = self.program.routines[(write, size)]
        return self._run(pc, pc + 2, addr, value, board)

    def _run(self, pc: int, done_pc: int, r0: int, r1: int, board: int) -> int:
        p1 = self.ffi.new("uint32_t *", r1 & 0xFFFFFFFF)
        t0 = self.ffi.new("uint64_t *")
        if self.lib.sam_harness_call(self._w, board, pc, done_pc, r0 & 0xFFFFFFFF, p1, t0):
            raise HarnessError(self.error(board) or "the board stopped")
        self.t_access = int(t0[0])
        return int(p1[0])

    def call(self, label: str, done: str, *, r0: int = 0, r1: int = 0, board: int = 0) -> int:
        """Run the program's code from `label` until the PC reaches `done` (labels of the stub's handlers code)
        with R0, R1 given; R1 there."""
        return self._run(self.program.labels[label], self.program.labels[done], r0, r1, board)

    def write(self, reg: str | int, value: int, size: int | None = None, *, board: int = 0) -> None:
        """Store `value` to a register (its own width, or `size` bytes) as the board's CPU would."""
        self._call(1, reg, value, size, board)

    def read(self, reg: str | int, size: int | None = None, *, board: int = 0) -> int:
        """Load a register as the board's CPU would."""
        return self._call(0, reg, 0, size, board)

    def field(self, reg: str, name: str) -> int:
        """The mask of a register's field from the table ("TC3.INTFLAG", "OVF")."""
        periph, rest = reg.split(".", 1)
        f = self.table.reg(periph, rest).field(name)
        if f is None:
            raise KeyError(f"{reg} has no field {name}")
        return f.mask

    def irq(self, periph: str) -> int:
        """The NVIC line of a peripheral ("TC3")."""
        irq = self.table.periph(periph).irq
        if irq is None:
            raise KeyError(f"{periph} has no interrupt line")
        return irq

    # ---- time ------------------------------------------------------------------------------------------
    def now(self, board: int = 0) -> int:
        """The board's time (tu)."""
        return int(self.lib.sam_harness_now(self._w, board))

    def tu(self, seconds: float) -> int:
        return round(seconds * self.tu_hz)

    def advance(self, seconds: float | None = None, *, cycles: int | None = None, tu: int | None = None) -> None:
        """Run the world (every board, the plant's windows) on from the latest board's time by seconds, CPU cycles
        (of board 0's clock now) or tu."""
        if cycles is not None:
            tu = cycles * self.nvic().cyc_tu
        elif seconds is not None:
            tu = self.tu(seconds)
        if tu is None:
            raise ValueError("advance: give seconds, cycles or tu")
        self.advance_to(max(self.now(b) for b in range(len(self.roles))) + tu)

    def advance_to(self, t_tu: int) -> None:
        """Run the world to time t (tu)."""
        if self.lib.sam_world_run(self._w, t_tu):
            raise HarnessError(self.ffi.string(self.lib.sam_world_error(self._w)).decode())

    # ---- pins, drivers ------------------------------------------------------------------------------------
    @staticmethod
    def pin_number(pin: str | int) -> int:
        return pin if isinstance(pin, int) else wiring.pin_number(pin)

    def pin(self, pin: str | int, level: int | None, *, board: int = 0) -> None:
        """Drive a pin from outside the board (0, 1; None releases it) from the board's time on."""
        lv = -1 if level is None else int(bool(level))
        if self.lib.sam_harness_pin(self._w, board, self.pin_number(pin), lv):
            raise HarnessError(f"pin {pin!r}: cannot drive it")

    def pin_state(self, pin: str | int, *, board: int = 0) -> PinState:
        s = self.ffi.new("sam_pin_info_t *")
        if self.lib.sam_harness_pin_state(self._w, board, self.pin_number(pin), s):
            raise HarnessError(f"pin {pin!r}: no such pin")
        return PinState(int(s.level), int(s.out), bool(s.driven), int(s.function))

    def motor(self, chain: int, *, cell: int = 0) -> tuple[float, float]:
        """What the plant saw of a cell's driver over the last window: (mean voltage, awake fraction)."""
        v, a = self.ffi.new("double *"), self.ffi.new("double *")
        if self.lib.sam_world_motor(self._w, cell, chain, v, a):
            raise HarnessError(f"cell {cell} chain {chain}: no such motor")
        return float(v[0]), float(a[0])

    def tcc_info(self, tcc: int = 0, *, board: int = 0):
        """A TCC as it counts now (csrc/sam_api.h sam_tcc_info_t): prescaler, PER, the current cycle's start and
        top, the PWM period in tu."""
        out = self.ffi.new("sam_tcc_info_t *")
        if self.lib.sam_world_tcc_info(self._w, board, tcc, out):
            raise HarnessError(f"board {board} TCC{tcc}: no such timer")
        return out

    def tcc_high(self, wo: int, t0: int, t1: int, *, tcc: int = 0, board: int = 0) -> int:
        """High time (tu) of TCCn/WO[wo] over [t0, t1) from the counter's edges (the waveform path's figure)."""
        return int(self.lib.sam_world_tcc_high(self._w, board, tcc, wo, t0, t1))

    def tcc_mean(self, wo: int, t0: int, t1: int, *, tcc: int = 0, board: int = 0) -> tuple[int, int, float]:
        """The mean path's figure for TCCn/WO[wo] over [t0, t1): (numerator, den, other), the mean high time being
        numerator / den + other tu (den: the first stretch's period in counts)."""
        den, other = self.ffi.new("uint64_t *"), self.ffi.new("double *")
        hi = int(self.lib.sam_world_tcc_mean(self._w, board, tcc, wo, t0, t1, den, other))
        return hi, int(den[0]), float(other[0])

    # ---- the core ----------------------------------------------------------------------------------------
    def nvic(self, *, board: int = 0):
        n = self.ffi.new("sam_nvic_info_t *")
        self.lib.sam_harness_nvic(self._w, board, n)
        return n

    def pending(self, *, board: int = 0) -> set[int]:
        """External IRQ lines pending in the NVIC."""
        p = int(self.nvic(board=board).pending)
        return {i for i in range(32) if p >> i & 1}

    def active(self, *, board: int = 0) -> set[int]:
        a = int(self.nvic(board=board).active)
        return {i for i in range(32) if a >> i & 1}

    def info(self, *, board: int = 0):
        """sam_mcu_info_t: time, cycles, resets and the last reset's cause (PM.RCAUSE bits), the core's state."""
        o = self.ffi.new("sam_mcu_info_t *")
        self.lib.sam_world_mcu_info(self._w, board, o)
        return o

    def ram(self, addr: int, n: int, *, board: int = 0) -> bytes:
        buf = self.ffi.new("uint8_t[]", n)
        if self.lib.sam_world_read_mem(self._w, board, addr, buf, n):
            raise HarnessError(f"0x{addr:08x}+{n}: not SRAM or flash")
        return bytes(self.ffi.buffer(buf, n))

    def set_user_row(self, data: bytes, *, board: int = 0) -> None:
        """Program the NVM user row's first bytes (BOOTPROT, the region lock bits), as a programmer does before
        power-up: NVMCTRL reloads LOCK and BOOTPROT from it."""
        if self.lib.sam_world_set_user_row(self._w, board, data, len(data)):
            raise HarnessError("set_user_row: no such board or too long")

    def error(self, board: int = 0) -> str | None:
        e = self.lib.sam_harness_error(self._w, board)
        return None if e == self.ffi.NULL else self.ffi.string(e).decode()

    def notes(self) -> list[str]:
        buf = self.ffi.new("char[]", 1 << 20)
        n = self.lib.sam_world_notes(self._w, buf, 1 << 20)
        return [ln for ln in self.ffi.unpack(buf, n).decode(errors="replace").splitlines() if ln]
