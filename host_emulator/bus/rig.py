"""The emulated rig's data path: hil plant + compiled cells with their register handlers + compiled primary, on an I2C
timing model.

Time is integer microseconds of simulated time. Events, in time order:
  * control tick k at k * tick_us: every cell with a pending write runs
    mc_regs_apply (the tick boundary), then the compiled plant loop runs the
    tick (mc_cell_tick of all cells, motors, encoders; he_hil_run);
  * a read's onRequest, after START + address byte: the cell's register
    handler publishes the block of its last tick (lazily: once per tick at
    most, with the decoder counters as they are then) and copies it out;
  * a write's onReceive at its STOP;
  * a transaction's completion, reported to the primary (mc_primary_complete),
    followed by the primary's next transaction after `sw_overhead_us`
    (the glue's per-transaction software time).
Fault injection per cell: `absent` (address NACK), `stuck` (holds SCL until
the primary's per-transaction timeout aborts it), `babble` (random bytes).
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .. import firmware
from ..construct import checked_solver
from ..controller import build_solver
from ..models.hil import HilSolver
from ..models.plant import NumericalInstability
from ..scene import load_scene
from .i2c import I2CTiming

if TYPE_CHECKING:
    from ..models.hil import HilSolver


@dataclass
class BusOptions:
    i2c_hz: int = 400_000
    period_us: int = 0  # full-cycle period, 0 = back to back
    sw_overhead_us: int = 10  # primary software time per transaction
    stretch_us: int = 0  # SCL held by a secondary while its onRequest runs
    txn_timeout_us: int | None = None  # default: 2 x longest block read + 200 us
    ack_timeout_us: int = 50_000
    status_every: int = 64
    absent: tuple = ()
    stuck: tuple = ()
    babble: tuple = ()
    build: int = 0
    seed: int = 1


class EmulatedRig:
    """Compiled cells (mc_regs_t + the hil solver's mc_cell_t) and primary (mc_link_t) on the emulated bus."""

    def __init__(self, solver: HilSolver, opts: BusOptions | None = None) -> None:
        self.opts = opts = opts or BusOptions()
        self.ffi, self.lib = firmware.load()
        ffi, lib = self.ffi, self.lib
        self.solver = solver
        self.n = solver.model.n
        if self.n > lib.MC_MAX_CELLS:
            raise ValueError(f"the bus addresses at most {lib.MC_MAX_CELLS} cells, the scene has {self.n}")
        self.timing = I2CTiming(opts.i2c_hz)
        rate = solver.model.rate_hz
        if 1_000_000 % rate:
            raise ValueError(f"control rate {rate} Hz does not divide 1 s in whole microseconds")
        self.tick_us = 1_000_000 // rate
        self.regs = ffi.new("mc_regs_t[]", self.n)
        for j in range(self.n):
            if (
                lib.mc_regs_init(
                    self.regs + j, solver.cells + j, lib.MC_ADDR_BASE + j, opts.build, solver.model.cell_phys[j]
                )
                != lib.MC_OK
            ):
                raise ValueError("register handler refused its address")
        self.link = ffi.new("mc_link_t *")
        lib.mc_link_init(self.link, 0)
        # the primary polls the rig as built (16 cells; a smaller scene leaves the rest absent) or a bigger sheet's
        # every cell, as its firmware built with -DMC_RIG_CELLS=n does
        self.polled = max(self.n, lib.MC_N_CELLS)
        if self.polled != lib.MC_N_CELLS and lib.mc_primary_set_cells(ffi.addressof(self.link, "p"), self.polled):
            raise ValueError(f"the primary refused to poll {self.polled} cells")
        longest = max(lib.MC_BLK_SNAPSHOT_LEN, lib.MC_BLK_PARAMS_LEN, lib.MC_BLK_IDENT_LEN, lib.MC_WRITE_MAX_LEN)
        tmo = opts.txn_timeout_us or int(2e6 * self.timing.transaction_s(longest)) + 200
        if (
            lib.mc_primary_configure(
                ffi.addressof(self.link, "p"), opts.period_us, tmo, opts.ack_timeout_us, opts.status_every
            )
            != 0
        ):
            raise ValueError(
                f"primary refused period_us={opts.period_us}, txn_timeout_us={tmo}, "
                f"ack_timeout_us={opts.ack_timeout_us}, status_every={opts.status_every}"
            )
        self.p = ffi.addressof(self.link, "p")
        self.txn = ffi.new("mc_txn_t *")
        self.rxbuf = ffi.new("uint8_t[64]")
        self.outbuf = ffi.new("char[]", 8192)
        self.replybuf = ffi.new("char[]", 4096)
        self.used = ffi.new("uint32_t *")
        self._early = bytearray()  # frames drained while feeding input
        self.qa = ffi.new("mc_quad_snap_t *")
        self.qb = ffi.new("mc_quad_snap_t *")
        self.rng = random.Random(opts.seed)
        self.t_us = 0
        self.next_tick_us = 0
        self.published_tick = [-1] * self.n
        self.bus_free_us = 0  # when the primary may start its next transaction
        self.pending: list[tuple[int, str, tuple | None]] = []  # (time_us, kind, payload) of the transaction in flight
        self.ticks = 0
        self.band_stops = 0  # plant range stops turned into runaway faults
        self.transactions = 0
        self.bus_busy_us = 0.0

    # ---- cells ---------------------------------------------------------------
    def _snap(self, j):
        lib, q = self.lib, self.solver.quad
        lib.mc_quad_snapshot(q + j, self.qa)
        lib.mc_quad_snapshot(q + self.n + j, self.qb)

    def _tick(self):
        lib = self.lib
        for j in range(self.n):
            if self.regs[j].rx_full:
                self._snap(j)
                lib.mc_regs_apply(self.regs + j, self.solver.cells + j, self.qa, self.qb)
        try:
            # he_hil_run: mc_cell_tick of every cell, motors, plant, encoders (and the scene's firmware commands)
            self.solver.run_ticks(1)
        except NumericalInstability:
            if not self._band_stop():
                raise
            self.solver.run_ticks(1)
        self.ticks += 1
        self.next_tick_us += self.tick_us

    def _band_stop(self) -> bool:
        """The plant left its physical range (a band stretched past the stop of its fit): on the rig
        the cylinders hit that range and the cells' runaway check trips. Emulated as such: the bond's
        pair (a chain's neighbours, or a sheet's bond from the plant's edge list) is put back just
        inside the range at rest, both cells latch MC_FAULT_RUNAWAY of that chain
        (drives off until CLEAR_FAULTS), and the rig runs on. False if the cause was something else."""
        lib, sol = self.lib, self.solver
        plant = sol.h.plant
        where = self.ffi.new("int *", -1)
        px = self.ffi.from_buffer("double[]", sol.x)
        n = self.n
        hit = False
        for _ in range(8 * n):  # each pass puts one pair back; neighbours may follow
            if lib.he_plant_range_check(plant, px, where) != lib.HE_ERR_BAND or where[0] < 0:
                break
            if plant.bonds != self.ffi.NULL:  # an edge list (ring, sheet): where = bond + chain * nbond
                ch, e = divmod(where[0], plant.nbond)
                i, k = int(plant.bonds[2 * e]), int(plant.bonds[2 * e + 1])
            else:  # the open chain: where = j + chain * n, the bond (j, j + 1)
                ch, i = divmod(where[0], n)
                k = i + 1
            lim = (lib.HE_BAND_STOP_FACTOR * plant.delta_max[ch] - plant.delta0[ch]) / plant.lever[ch]
            a, b = ch * n + i, ch * n + k
            mid, half = (sol.x[a] + sol.x[b]) / 2, 0.95 * lim / 2
            d = 1.0 if sol.x[a] >= sol.x[b] else -1.0
            sol.x[a], sol.x[b] = mid + d * half, mid - d * half
            sol.v[a] = sol.v[b] = 0.0
            bit = lib.MC_FAULT_RUNAWAY_A if ch == 0 else lib.MC_FAULT_RUNAWAY_B
            for c in (i, k):
                sol.cells[c].faults |= bit
            hit = True
        if not hit or lib.he_plant_range_check(plant, px, where) == lib.HE_ERR_BAND:
            return False
        self.band_stops += 1
        return True

    def _on_request(self, j, nbytes):
        if self.published_tick[j] != self.ticks:
            self._snap(j)
            self.lib.mc_regs_publish(self.regs + j, self.solver.cells + j, self.qa, self.qb)
            self.published_tick[j] = self.ticks
        n = self.lib.mc_regs_on_request(self.regs + j, self.rxbuf, len(self.rxbuf))
        data = bytes(self.ffi.buffer(self.rxbuf, n))
        # an empty transmit buffer reads as 0xFF (SAMD21 Wire)
        return (data + b"\xff" * nbytes)[:nbytes]

    # ---- bus -----------------------------------------------------------------
    def _start(self, now):
        lib, t = self.lib, self.txn
        if not lib.mc_primary_next(self.p, now & 0xFFFFFFFF, t):
            return False
        j, kind, nbytes = t.cell, t.kind, t.len
        cell = j + 1
        tm = self.timing
        self.transactions += 1
        if j >= self.n or cell in self.opts.absent:
            dur = tm.nack_s()
            self.pending = [(now + round(dur * 1e6), "done", (lib.MC_I2C_NACK_ADDR, b""))]
        elif cell in self.opts.stuck:
            dur = t.timeout_us * 1e-6
            self.pending = [(now + t.timeout_us, "done", (lib.MC_I2C_TIMEOUT, b""))]
        elif kind == lib.MC_TXN_READ:
            dur = tm.transaction_s(nbytes) + self.opts.stretch_us * 1e-6
            self.pending = [
                (now + round(tm.request_offset_s() * 1e6), "request", (j, nbytes)),
                (now + round(dur * 1e6), "done", None),
            ]
        else:
            dur = tm.transaction_s(nbytes)
            data = bytes(self.ffi.buffer(t.buf, nbytes))
            end = now + round(dur * 1e6)
            self.pending = [(end, "receive", (j, data)), (end, "done", (lib.MC_I2C_OK, b""))]
        self.bus_busy_us += dur * 1e6
        return True

    def _bus_event(self):
        when, kind, arg = self.pending.pop(0)
        if arg is None:  # a read's completion gets its data from the request event before it
            raise RuntimeError(f"bus event {kind!r} at {when} us without its data")
        lib = self.lib
        if kind == "request":
            j, nbytes = arg
            if j + 1 in self.opts.babble:
                data = bytes(self.rng.randrange(256) for _ in range(nbytes))
            else:
                data = self._on_request(j, nbytes)
            self.pending[0] = (self.pending[0][0], "done", (lib.MC_I2C_OK, data))
        elif kind == "receive":
            j, data = arg
            self.lib.mc_regs_on_receive(self.regs + j, data, len(data))
        else:
            status, data = arg
            lib.mc_primary_complete(self.p, when & 0xFFFFFFFF, status, data, len(data))
            self.bus_free_us = when + self.opts.sw_overhead_us

    def advance_to(self, t_end_us: int) -> None:
        """Run ticks and bus events up to simulated time t_end_us."""
        while True:
            if not self.pending and self.bus_free_us <= self.next_tick_us and self.bus_free_us <= t_end_us:
                now = max(self.bus_free_us, self.t_us)
                self.t_us = now
                if not self._start(now) and not self._start(now):
                    self.bus_free_us = now + 20  # primary idle (period not due): look again in 20 us
                continue
            t_bus = self.pending[0][0] if self.pending else None
            if t_bus is not None and t_bus < self.next_tick_us and t_bus <= t_end_us:
                self.t_us = t_bus
                self._bus_event()
            elif self.next_tick_us <= t_end_us and (t_bus is None or self.next_tick_us <= t_bus):
                self.t_us = self.next_tick_us
                self._tick()
            else:
                self.t_us = t_end_us
                return

    # ---- laptop side ---------------------------------------------------------
    USB_CHUNK = 64  # bytes the primary takes from USB between two queue drains (one CDC packet)

    def feed(self, data: bytes) -> bytes:
        """Bytes from the laptop at the current time; returns the SLCAN replies.

        Taken one USB packet at a time with the queue drained in between, as the
        firmware's loop does; the drained frames come out of the next drain()."""
        out = bytearray()
        while data:
            piece = data[: self.USB_CHUNK]
            n = self.lib.mc_link_rx(
                self.link, self.t_us & 0xFFFFFFFF, piece, len(piece), self.used, self.replybuf, len(self.replybuf)
            )
            out += self.ffi.buffer(self.replybuf, n)
            data = data[self.used[0] :]
            if len(data):
                self._early += self._drain()
        return bytes(out)

    def session(self) -> None:
        """The host opened or closed the port: channel closed, stale frames and half line dropped."""
        self._early.clear()
        self.lib.mc_link_session(self.link)

    def drain(self) -> bytes:
        """SLCAN text of every queued frame (empty while the channel is closed)."""
        out = bytes(self._early) + self._drain()
        self._early.clear()
        return out

    def _drain(self) -> bytes:
        out = bytearray()
        while True:
            n = self.lib.mc_link_tx(self.link, self.t_us & 0xFFFFFFFF, self.outbuf, len(self.outbuf))
            if n == 0:
                return bytes(out)
            out += self.ffi.buffer(self.outbuf, n)

    def frames(self) -> list[tuple[int, bytes]]:
        """Pop queued frames as (id, bytes) without the SLCAN text layer."""
        f = self.ffi.new("mc_can_frame_t *")
        out = []
        while self.lib.mc_primary_pop(self.p, f):
            out.append((f.id, bytes(f.data)[: f.dlc]))
        return out

    def angles(self) -> tuple[list[float], list[float]]:
        """Plant angles (alpha, beta) in counts."""
        import math

        n = self.n
        k = self.lib.MC_COUNTS_PER_REV / (2 * math.pi)
        return [x * k for x in self.solver.x[:n]], [x * k for x in self.solver.x[n:]]


def make_rig(scene_name: str = "default", opts: BusOptions | None = None, overrides=()):
    """EmulatedRig over the hil model of a scene (the scene must use model = "hil"), built as a run builds it
    (controller.build_solver: the scene's accuracy preset applies)."""
    sc = load_scene(scene_name, overrides)
    if sc.model == "image":  # the flashed primary itself on the pty (host_emulator/image/serve.py)
        if opts is not None and opts != BusOptions(i2c_hz=opts.i2c_hz):
            raise ValueError(
                "--absent, --stuck, --babble and --period-us drive the hil rig's bus model; the image tier runs the "
                "real firmware: give faults as [[fault]] tables (--set fault.1.kind=silent ...)"
            )
        if opts is not None and opts.i2c_hz != 400_000:
            raise ValueError("--i2c-hz: the image tier's primary sets its own bus clock (400 kHz, its firmware)")
        from ..image.serve import make_image_rig

        return make_image_rig(checked_solver(sc)), sc  # the run's cost judged before the boards boot
    if sc.model != "hil":
        raise ValueError(f'scene {sc.name!r} uses model {sc.model!r}; serving the bus needs model = "hil" or "image"')
    solver = build_solver(sc)
    if not isinstance(solver, HilSolver):
        raise TypeError(f"model hil built a {type(solver).__name__}")
    return EmulatedRig(solver, opts), sc
