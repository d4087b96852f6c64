"""A world of boards running flashed images on the plant: the Python face of the compiled runtime (csrc/sam_world.c)."""

from __future__ import annotations

import math
import struct
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..models.options import ModelOptions, Perturbation
from ..models.plant import build_plant
from ..models.steppers import stepper_id
from ..params import Params
from . import board, bootloader, cycles, runtime
from .build import ImageSet
from .elfimage import FirmwareImage, Segment, load_image

NOTES_KEPT = 100_000  # log lines World.notes keeps
API_S = 50e-6  # an action from outside lands this long after the world's time (csrc/sam_usb.c: USB_API_S)


USB_PROFILES = ("script", "linux")  # csrc/sam_api.h SAM_USB_PROFILE_*


@dataclass(frozen=True)
class UsbDevice:
    """A board's USB device as the laptop's host read it (World.usb_device; csrc/sam_api.h sam_usb_device_t)."""

    vid: int
    pid: int
    bcd_usb: int
    bcd_device: int
    manufacturer: str  # the strings: "" unless the Linux profile read them
    product: str
    serial: str
    comm_if: int  # the CDC comm interface (wIndex of class requests)
    data_in: int  # the CDC data endpoints
    data_out: int
    enumerations: int  # times the device was configured
    detaches: int  # times it left the bus after it had been seen
    baud: int  # the line coding last sent (0: none since it enumerated)
    dtr: bool  # the control line state last sent
    rts: bool
    described: bool  # its device descriptor was read in this enumeration


class WorldError(RuntimeError):
    """The world stopped: a board did something the models do not cover, or the plant failed. The message names
    the board, the register or the cause, the program counter and the time."""


@dataclass
class WorldConfig:
    window_s: float = 50e-6  # plant window (the lag between a motor's voltage and the plant's response)
    substeps: int = 1  # plant steps per window
    round_s: float = 0.0  # longest time boards run apart before the world meets them again; 0: the window
    ff: bool = True  # fast-forward provably idle loop() passes
    ff_timed: bool = True  # and passes that read the time (a polling loop's), each after a probe (csrc/sam_ff.c)
    cycle_model: str = "cache"  # "cache": flash waits on NVM cache misses; "worst": the CPU budget's bound
    i2c_rise_ns: float = 125.0  # SCL rise time on the rig's bus (part of each SCL period)
    usb_packet_us: float = 50.0  # the laptop's USB host: time to move one packet
    trace: int = 0  # bit 0: every I2C bus step in the notes; bit 2: every register access of trace_boards
    trace_boards: int = 0  # bit b: board b
    threads: int = 1  # threads the boards run on (1..16); results do not depend on it
    # "direct": the application starts at 0x2000 at once (the bootloader's hand-off simulated: every existing result);
    # "bootloader": the XIAO's UF2 bootloader (MC_BOOTLOADER, image/bootloader.py) runs from the reset vector and
    # starts the application itself (+6.9 ms after power-on, +0.9 s after any other reset). Without MC_BOOTLOADER
    # the boards boot directly, with one line saying so (blank boards need it: an error).
    boot: str = "direct"
    blank: bool = False  # boot = "bootloader" only: the boards hold the bootloader alone, as new XIAOs arrive
    # BOOTPROT of the boards' NVM user row: 7 (nothing protected) is assumed, the shipped XIAOs' fuse being unknown;
    # 2 protects the bootloader's 8 KiB (csrc/sam.h SAM_NVM_BOOTPROT_ASSUMED, csrc/sam_nvmctrl.c)
    bootprot: int = 7
    # what the motors see of a PWM output: "mean" (the duty CC / (PER + 1) over each window's time: every result
    # before the waveform existed) or "waveform" (each output's edges from the TCC counter's phase, prescaler and
    # period: a window sees the real high time); docs/image-tier.md "PWM and the motors"
    pwm: str = "mean"
    # "waveform" only: the motors' electrical time constant L / R, s (0: none; MOTOR_TAU_S is the estimate)
    motor_tau_s: float = 0.0


#: The coreless motors' terminal resistance and inductance (docs/image-tier.md "PWM and the motors"): R from the
#: stall figures of docs/physics.md (12 V / 4.3 A); L an estimate (no datasheet value: small coreless DC motors have
#: tens to hundreds of uH), so tau_e = L / R = 36 us against the 50 us PWM period.
MOTOR_R_OHM = 12.0 / 4.3
MOTOR_L_H = 100e-6
MOTOR_TAU_S = MOTOR_L_H / MOTOR_R_OHM
PWM_PATHS = ("mean", "waveform")  # models/options.py PWM_PATHS


def set_pwm(c, pwm: str, motor_tau_s: float) -> None:
    """The PWM path and the motors' time constant into a sam_world_cfg_t (ValueError naming the bad value)."""
    if pwm not in PWM_PATHS:
        raise ValueError(f"pwm = {pwm!r}: expected one of {', '.join(PWM_PATHS)}")
    if not (math.isfinite(motor_tau_s) and motor_tau_s >= 0):
        raise ValueError(f"motor_tau_s = {motor_tau_s!r}: expected a time constant >= 0 s")
    if motor_tau_s and pwm != "waveform":
        raise ValueError(f"motor_tau_s = {motor_tau_s!r}: the electrical model needs pwm = 'waveform'")
    c.pwm_waveform = int(pwm == "waveform")
    c.motor_tau_s = motor_tau_s


@dataclass
class Board:
    index: int
    name: str
    role: str  # "cell" | "primary"
    cell: int | None  # 1-based
    image: FirmwareImage | None  # None: a blank board (the bootloader alone)
    keep: list = field(default_factory=list, repr=False)


class World:
    """Boards (16 cells and the primary by default) on the plant of `params`, from power-up (time 0)."""

    def __init__(
        self,
        params: Params,
        images: ImageSet | None,
        *,
        options: ModelOptions | None = None,
        perturbations: Sequence[Perturbation] = (),
        config: WorldConfig | None = None,
        primary: bool = True,
        x0=None,
    ) -> None:
        self.ffi, self.lib = runtime.load()
        ffi, lib = self.ffi, self.lib
        self.params = params
        self.config = cfg = config or WorldConfig()
        self.options = options or ModelOptions()
        n = params.cells
        self.boot_bin = self._bootloader(cfg)
        self.boot = "bootloader" if self.boot_bin is not None else "direct"
        if cfg.blank:
            images = None
        elif images is None or len(images.cells) < n:
            raise ValueError(f"{n} cells but images for {0 if images is None else len(images.cells)}")
        self.n = n
        self.plant = build_plant(ffi, lib, params, self.options, n, list(perturbations), ideal_reaction=False)
        self.x = np.zeros(2 * n) if x0 is None else np.array(x0, dtype=float).reshape(2 * n)
        self.v = np.zeros(2 * n)
        self.tu_hz = int(lib.sam_tu_hz())
        c = ffi.new("sam_world_cfg_t *")
        c.ncells = n
        c.primary = 1 if primary else 0
        c.window_s = cfg.window_s
        c.substeps = cfg.substeps
        c.stepper = stepper_id(lib, self.options.stepper)
        c.supply_v = params.supply_v
        c.kt = params.kt
        c.counts_per_rad = lib.MC_COUNTS_PER_REV / (2 * math.pi)
        c.i2c_rise_ns = cfg.i2c_rise_ns
        c.usb_packet_us = cfg.usb_packet_us
        c.ff = 1 if cfg.ff else 0
        c.ff_timed = 1 if cfg.ff_timed else 0
        if cfg.cycle_model not in cycles.CYCLE_MODELS:
            raise ValueError(f"cycle_model = {cfg.cycle_model!r}: expected one of {', '.join(cycles.CYCLE_MODELS)}")
        c.cycle_model = cycles.CYCLE_MODELS.index(cfg.cycle_model)
        c.round_s = cfg.round_s
        c.threads = cfg.threads
        cm = cycles.CycleModel()
        c.cyc_exc_entry, c.cyc_exc_exit, c.cyc_apb = cm.exc_entry, cm.exc_exit, cm.apb_extra
        c.trace = cfg.trace
        c.trace_boards = cfg.trace_boards
        c.plant = self.plant
        set_pwm(c, cfg.pwm, cfg.motor_tau_s)
        self._px = ffi.from_buffer("double[]", self.x)
        self._pv = ffi.from_buffer("double[]", self.v)
        c.x = self._px
        c.v = self._pv
        board.wire(c)
        self._cfg = c
        wp = ffi.new("sam_world_t **")
        rc = lib.sam_world_new(wp, c)
        self._w = ffi.gc(wp[0], lib.sam_world_free)
        if rc != 0:
            raise WorldError(ffi.string(lib.sam_world_error(self._w)).decode())
        self.boards: list[Board] = []
        self._notes: list[str] = []
        for j in range(1, n + 1):
            self._load(None if images is None else load_image(images.cells[j - 1]), f"cell {j}", "cell", j)
        self.primary = None
        if primary:
            img = None if images is None else load_image(images.primary)
            self.primary = self._load(img, "primary", "primary", None)

    @staticmethod
    def _bootloader(cfg: WorldConfig) -> bytes | None:
        """The bootloader's bytes when the boards boot through it (None: direct boot)."""
        if cfg.boot not in bootloader.BOOT_MODES:
            raise ValueError(f"boot = {cfg.boot!r}: expected one of {', '.join(bootloader.BOOT_MODES)}")
        if cfg.boot == "direct":
            if cfg.blank:
                raise ValueError("blank boards need boot = 'bootloader'")
            return None
        if bootloader.path() is None and not cfg.blank:
            print(bootloader.unavailable() + "; the applications start directly", file=sys.stderr)
            return None
        try:
            return bootloader.load()
        except bootloader.BootloaderError as e:
            raise WorldError(str(e)) from None

    def _load(self, img: FirmwareImage | None, name: str, role: str, cell: int | None) -> Board:
        ffi, lib = self.ffi, self.lib
        idx = len(self.boards)
        b = Board(idx, name, role, cell, img)
        boot = self.boot_bin
        segments = list(img.segments) if img is not None else []
        if boot is not None:
            segments.insert(0, Segment(0, boot))
        else:
            assert img is not None
        segs = ffi.new("sam_seg_t[]", len(segments))
        for i, s in enumerate(segments):
            buf = ffi.new("uint8_t[]", s.data)
            b.keep.append(buf)
            segs[i].addr = s.addr
            segs[i].len = len(s.data)
            segs[i].data = buf
        im = ffi.new("sam_image_t *")
        im.segs = segs
        im.nsegs = len(segments)
        if img is not None:
            im.entry_sp, im.entry_pc = img.entry_sp, img.entry_pc
            im.loop_pc = img.symbols.get("loop", (0, 0))[0]
            im.heap_base, im.brk_var = img.heap_base, img.brk_var
        else:  # blank: the bootloader's vector table (the entry is used by direct boot only)
            assert boot is not None
            im.entry_sp, im.entry_pc = struct.unpack_from("<II", boot)
        im.boot = int(boot is not None)
        t = img.tables if img is not None else None
        if t is not None:  # the ELF's tables (else, and outside them, the decoder costs each block from the flash)
            core = ffi.from_buffer("uint32_t[]", t.core)
            wait = ffi.from_buffer("uint32_t[]", t.wait)
            lit = ffi.from_buffer("uint32_t[]", t.literal)
            refund = ffi.from_buffer("uint8_t[]", t.refund)
            im.cost_core, im.cost_wait, im.cost_lit, im.refund = core, wait, lit, refund
            im.code_end = t.code_end
            b.keep += [core, wait, lit, refund]
        b.keep += [segs, t, im]
        rc = lib.sam_world_load(
            self._w,
            idx,
            im,
            name.encode(),
            lib.SAM_ROLE_CELL if role == "cell" else lib.SAM_ROLE_PRIMARY,
            (cell - 1) if cell else -1,
        )
        if rc != 0:
            raise WorldError(ffi.string(lib.sam_world_error(self._w)).decode())
        if self.config.bootprot != bootloader.BOOTPROT_ASSUMED:
            row = bytes([0xF8 | (self.config.bootprot & 7)])
            lib.sam_world_set_user_row(self._w, idx, row, 1)
        self.boards.append(b)
        return b

    # ---- time ------------------------------------------------------------------
    def tu(self, seconds: float) -> int:
        return round(seconds * self.tu_hz)

    @property
    def t(self) -> float:
        return int(self.lib.sam_world_time(self._w)) / self.tu_hz

    def run_to(self, t_s: float) -> None:
        """Run every board and the plant to world time t_s (WorldError if the run stops)."""
        if self.lib.sam_world_run(self._w, self.tu(t_s)) != 0:
            raise WorldError(self.ffi.string(self.lib.sam_world_error(self._w)).decode())

    def start_plant(self, at_s: float | None = None) -> float:
        """The plant's clock starts (scene time 0): now, or at world time at_s."""
        t = self.t if at_s is None else at_s
        self.lib.sam_world_start_plant(self._w, self.tu(t))
        return t

    def trace(self, what: int, boards: int = 0) -> None:
        """Trace into the notes from now on (WorldConfig.trace bits; boards: bit b for board b)."""
        self.lib.sam_world_set_trace(self._w, what, boards)

    def notes(self) -> list[str]:
        """Every log line so far (resets, faults, USB errors, traces), oldest first (the newest NOTES_KEPT)."""
        buf = self.ffi.new("char[]", 1 << 20)
        while True:
            n = self.lib.sam_world_notes(self._w, buf, 1 << 20)
            if not n:
                break
            self._notes += [ln for ln in self.ffi.unpack(buf, n).decode(errors="replace").splitlines() if ln]
        del self._notes[:-NOTES_KEPT]
        return list(self._notes)

    def take_notes(self) -> list[str]:
        """The log lines since the last take_notes (for traces read as they come)."""
        out = self.notes()
        self._notes.clear()
        return out

    # ---- faults ----------------------------------------------------------------
    def fault(
        self, kind: str, t0_s: float, t1_s: float | None = None, *, board: int = -1, arg: float = 0.0, arg2: int = 0
    ) -> None:
        """Inject a fault (csrc/sam_api.h: SAM_FAULT_<KIND>) on board `board` for world time [t0_s, t1_s)."""
        code = getattr(self.lib, f"SAM_FAULT_{kind.upper()}", None)
        if not isinstance(code, int) or code >= self.lib.SAM_FAULT_COUNT:
            raise ValueError(f"fault {kind!r}: the runtime has no such fault (csrc/sam_api.h SAM_FAULT_*)")
        t1 = t0_s if t1_s is None else t1_s
        rc = self.lib.sam_world_fault(self._w, code, board, self.tu(t0_s), self.tu(t1), arg, arg2)
        if rc != 0:
            raise ValueError(self.ffi.string(self.lib.sam_world_error(self._w)).decode())

    def nfaults(self) -> int:
        """Faults injected so far (the index of the next one, while the table has room)."""
        return int(self.lib.sam_world_nfaults(self._w))

    def fault_fired(self, k: int) -> tuple[str, int, float | None] | None:
        """(kind, board, world time it took effect or None: not yet) of the k-th fault injected (None: no such)."""
        out = self.ffi.new("sam_fault_info_t *")
        if self.lib.sam_world_fault_info(self._w, k, out) != 0:
            return None
        kind = next(
            (n[len("SAM_FAULT_") :].lower() for n in dir(self.lib)
             if n.startswith("SAM_FAULT_") and n != "SAM_FAULT_COUNT" and getattr(self.lib, n) == out.kind),
            str(out.kind),
        )  # fmt: skip
        fired = int(out.t_fired) / self.tu_hz if out.fired else None
        return kind, int(out.mcu), fired

    def reset(self, b: int) -> None:
        """A system reset of board b now, as NVIC_SystemReset does (reset cause SYST, RAM kept): it restarts where a
        reset starts it, re-initialising its USB (the host sees it go and enumerate again). Like a USB host action
        from outside (csrc/sam_usb.c USB_API_S) it lands 50 us after the world's time, or at the board's own time if
        a stall (NVMCTRL programming a row) has moved it past that (sam_world_fault): never in a board's past."""
        self.fault("reset", self.t + API_S, board=b)

    def spin(
        self, cell: int, chain: str, counts_per_s: float, t0_s: float, t1_s: float, back_and_forth: int = 0
    ) -> None:
        """Turn a cell's encoder (not its cylinder) at counts_per_s (< 0: backwards) over world time [t0_s, t1_s),
        back and forth by `back_and_forth` counts when given: quadrature edges on its pins as the encoder gives them.
        For tests and benchmarks with the plant at rest (refused once the plant runs: it drives the encoders)."""
        b = next((x for x in self.boards if x.cell == cell), None)
        if b is None or chain not in ("alpha", "beta") or back_and_forth < 0:
            raise ValueError(f"spin: cell {cell} chain {chain!r} ({back_and_forth}): no such encoder or swing")
        arg2 = (0 if chain == "alpha" else 1) | (back_and_forth << 1)
        self.fault("spin", t0_s, t1_s, board=b.index, arg=counts_per_s, arg2=arg2)

    # ---- boards ----------------------------------------------------------------
    def info(self, b: int):
        out = self.ffi.new("sam_mcu_info_t *")
        if self.lib.sam_world_mcu_info(self._w, b, out) != 0:
            raise IndexError(b)
        return out

    def read_mem(self, b: int, addr: int, n: int) -> bytes:
        buf = self.ffi.new("uint8_t[]", n)
        if self.lib.sam_world_read_mem(self._w, b, addr, buf, n) != 0:
            raise ValueError(f"board {b}: 0x{addr:08x}+{n} is not SRAM or flash")
        return bytes(buf)

    def symbol(self, b: int, name: str, fmt: str = "<I"):
        """A variable of a board's image, read from its SRAM (struct format)."""
        img = self.boards[b].image
        if img is None:
            raise KeyError(f"board {b} is blank: no symbol {name!r}")
        addr = img.symbol(name)
        val = struct.unpack(fmt, self.read_mem(b, addr, struct.calcsize(fmt)))
        return val[0] if len(val) == 1 else val

    def touched(self, b: int) -> list[tuple[str, int, int]]:
        """(register, reads, writes) of every register the board's image accessed."""
        t = self.lib.sam_world_touch(self._w, b)
        out = []
        for i in range(int(self.lib.sam_world_nregs())):
            r, w = int(t[2 * i]), int(t[2 * i + 1])
            if r or w:
                out.append((self.ffi.string(self.lib.sam_world_reg_name(i)).decode(), r, w))
        return out

    def register(self, b: int, name: str) -> int:
        """The stored value of a register of a board, by its full name ("SERCOM2.I2CM.CTRLA")."""
        idx = self._reg_index().get(name)
        if idx is None:
            raise KeyError(f"no register {name!r}")
        out = self.ffi.new("uint32_t *")
        self.lib.sam_world_reg_value(self._w, b, idx, out)
        return int(out[0])

    def _reg_index(self) -> dict[str, int]:
        if not hasattr(self, "_regidx"):
            self._regidx = {
                self.ffi.string(self.lib.sam_world_reg_name(i)).decode(): i
                for i in range(int(self.lib.sam_world_nregs()))
            }
        return self._regidx

    def profile(self, b: int) -> np.ndarray:
        """The board's cycle profile (cycles charged per block start, by address / 2), cumulative from the first
        call: the first call starts it."""
        p = self.lib.sam_world_profile(self._w, b)
        if p == self.ffi.NULL:
            raise MemoryError("profile")
        n = cycles.FLASH_SIZE // 2
        return np.frombuffer(self.ffi.buffer(p, 8 * n), dtype=np.uint64).copy()

    def tcc_info(self, b: int, tcc: int = 0):
        """A TCC of board b as it counts now (csrc/sam_api.h sam_tcc_info_t): prescaler, PER, the PWM period in tu
        (the PWM frequency is tu_hz / period_tu)."""
        out = self.ffi.new("sam_tcc_info_t *")
        if self.lib.sam_world_tcc_info(self._w, b, tcc, out) != 0:
            raise IndexError(f"board {b} TCC{tcc}")
        return out

    def bus_info(self):
        out = self.ffi.new("sam_bus_info_t *")
        self.lib.sam_world_bus_info(self._w, out)
        return out

    def motor(self, cell: int, chain: int) -> tuple[float, float]:
        v, a = self.ffi.new("double *"), self.ffi.new("double *")
        self.lib.sam_world_motor(self._w, cell - 1, chain, v, a)
        return float(v[0]), float(a[0])

    # ---- USB host --------------------------------------------------------------
    def usb_attach(self, b: int, profile: str = "script") -> None:
        """Plug the laptop's USB host into board b's port. profile: "script" (the tier's enumeration, the default)
        or "linux" (as Linux enumerates and cdc_acm probes: strings, BOS; see usb_device, usb_line)."""
        if profile not in USB_PROFILES:
            raise ValueError(f"USB profile {profile!r}: expected one of {', '.join(USB_PROFILES)}")
        if self.lib.sam_usb_set_profile(self._w, b, USB_PROFILES.index(profile)) != 0:
            raise ValueError(f"board {b}: no such board, or its USB host is already attached")
        if self.lib.sam_usb_attach(self._w, b) != 0:
            raise ValueError(f"board {b}: no such board")

    def usb_line(self, b: int, baud: int, dtr: bool, rts: bool) -> None:
        """The laptop's line state on board b's port, as cdc_acm sends it (a speed change: SET_LINE_CODING, baud 0
        keeps the speed; a DTR/RTS change: SET_CONTROL_LINE_STATE)."""
        if self.lib.sam_usb_set_line(self._w, b, baud, 1 if dtr else 0, 1 if rts else 0) != 0:
            raise ValueError(f"board {b}: USB not attached")

    def usb_device(self, b: int) -> UsbDevice:
        """What board b's device said in its last enumeration, its counters and the line state it was last sent."""
        d = self.ffi.new("sam_usb_device_t *")
        self.lib.sam_usb_device(self._w, b, d)
        s = self.ffi.string
        return UsbDevice(
            int(d.vid), int(d.pid), int(d.bcd_usb), int(d.bcd_device),
            s(d.manufacturer).decode(), s(d.product).decode(), s(d.serial).decode(),
            int(d.comm_if), int(d.data_in), int(d.data_out), int(d.enumerations), int(d.detaches),
            int(d.baud), bool(d.dtr), bool(d.rts), bool(d.described),
        )  # fmt: skip

    def usb_dtr(self, b: int, on: bool) -> None:
        if self.lib.sam_usb_set_dtr(self._w, b, 1 if on else 0) != 0:
            raise ValueError(f"board {b}: USB not attached")

    def usb_write(self, b: int, data: bytes) -> int:
        return int(self.lib.sam_usb_write(self._w, b, data, len(data)))

    def usb_read(self, b: int) -> bytes:
        """Every byte the board sent the laptop since the last read."""
        if not hasattr(self, "_usbbuf"):
            self._usbbuf = self.ffi.new("uint8_t[]", 65536)
        n = self.lib.sam_usb_read(self._w, b, self._usbbuf, 65536)
        return bytes(self.ffi.buffer(self._usbbuf, n))

    def usb_info(self, b: int):
        out = self.ffi.new("sam_usb_info_t *")
        self.lib.sam_usb_info(self._w, b, out)
        return out
