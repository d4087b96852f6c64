"""Run a scene on the rig through the primary (python-can): configure, zero, enable, perturb, log until steady,
always disable.

One `Experiment` owns the bus for the whole session. Every frame received (also while a
command waits for its result) goes to the python-can writers and to the current repeat's
`SampleDecoder` (metacell_tools/rigtools/logger/files.py, on protocol/capture.py), which finds the gaps in the
sequence counters.
Every command goes through `RigClient` (metacell_tools/rigtools/command.py) and its per-cell result
is checked and kept. Experiment time (perturbation starts, t_end, settle and relax windows)
runs on the primary's clock as carried by the samples, so a rehearsal on an emulator that
runs slower than real time keeps the experiment's timing; every wait is also bounded in
wall time: a silent or lost primary raises LinkError.
Whatever happens (end, error, Ctrl-C), `finish` sends ENABLE off to every cell and
checks the answers; cells it could not confirm are named in the summary and on stderr.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np

from host_emulator.analysis.observables import DEFAULT_TOL_RAD, is_steady
from metacell_common.cli import cells_text
from metacell_tools.rigtools import proto
from metacell_tools.rigtools.command import RigClient
from metacell_tools.rigtools.logger import RAD_PER_COUNT, SampleDecoder

from .plan import Command, ExperimentPlan

_RESULT_BASE = proto.FRAMES["CMD_RESULT"]["base"]
_RESULT_IDS = frozenset(_RESULT_BASE + j for j in range(1, proto.MAX_CELLS + 1))  # CMD_RESULT of every cell
_PERTURB_ID = proto.REGISTERS["PERTURB"]["id"]


class LinkError(RuntimeError):
    """The primary stopped answering (port lost, no frames for `silence_s`)."""


class CommandFailed(RuntimeError):
    """A setup command was not answered OK by every cell (and --keep-going was not given)."""


@dataclass
class Options:
    repeats: int = 1
    settle_s: float = 1.0  # steady window: stop once every cell moved < 2 counts over this long
    early_stop: bool = True  # stop a repeat when steady (after the last perturbation ended)
    relax_s: float = 3.0  # drive off between repeats: the bands bring the chains to a uniform rest
    rest_timeout_s: float = 10.0  # longest wait for the lattice to be still before zeroing
    keep_going: bool = False  # continue past failed setup commands (those cells stay disabled)
    silence_s: float = 2.0  # no frame for this long = link lost
    cmd_timeout_s: float = 1.0  # per command, plus 0.1 s per addressed cell (RigClient)
    formats: tuple = ("asc",)  # python-can log formats


@dataclass
class Repeat:
    index: int
    decoder: SampleDecoder
    t0: float | None = None  # primary clock (decoder t_s) when every cell acknowledged ENABLE on
    t_stop: float | None = None  # primary clock when the run was stopped
    stopped: str = "not started"  # steady | t_end | aborted: <why>
    perturbations: list = field(default_factory=list)
    rest_counts: dict | None = None  # angles before ZERO: what the previous run left (counts)
    enabled_cells: list = field(default_factory=list)


class Experiment:
    """A session on one open python-can bus."""

    def __init__(
        self,
        bus,
        plan: ExperimentPlan,
        out: Path,
        opts: Options | None = None,
        report=None,
        hook=None,
        live=None,
        source: str = "rig",
    ):

        self.bus, self.plan, self.out = bus, plan, Path(out)
        self.source = source  # "rig", or "rehearsal:<model>" against the emulator: names files, summary and plots
        self.opts = opts or Options()
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.hook = hook or (lambda event, **kw: None)  # test and instrumentation point: hook(event, ...)
        self.out.mkdir(parents=True, exist_ok=True)
        stem = "rig" if source == "rig" else source.split(":")[0]  # rig.asc, or rehearsal.asc: never a rehearsal as rig
        self.log_files = [self.out / f"{stem}.{f}" for f in self.opts.formats]
        self.writers = [can.Logger(str(p)) for p in self.log_files]
        self.client = RigClient(bus, self.opts.cmd_timeout_s, on_message=self._take)
        self.n_decode = max(proto.N_CELLS, len(plan.cells))  # the rig as built's 16, or a bigger sheet's every cell
        self.idle = SampleDecoder(self.n_decode, report=lambda text: None)  # frames outside a repeat (rest checks)
        self.decoder = self.idle
        self.frames = 0
        self.corrupt = 0  # SLCAN lines python-can could not parse
        self.last_frame = time.monotonic()
        self.commands: list[dict] = []  # every command: {phase, reg, label, results}
        self.failures: list[dict] = []  # {phase, reg, label, cell, result} of every non-OK answer
        self.repeats: list[Repeat] = []
        self.safe: list[int] | None = None  # result of the final ENABLE off
        self.identity: dict = {}  # {cell: IDENT block fields, or {"error": ...}} read before the first repeat
        self.live = live  # metacell_tools.experiment.live.RigLive or None: live plot fed from the logged frames
        self._acks: dict | None = None  # while a PERTURB waits: {cell: primary clock when its CMD_RESULT came}
        self.t_session = time.time()

    # ---- frames --------------------------------------------------------------
    def _take(self, msg):
        self.frames += 1
        self.last_frame = time.monotonic()
        for w in self.writers:
            w.on_message_received(msg)
        self.decoder.feed(msg)
        if self._acks is not None and msg.arbitration_id in _RESULT_IDS and msg.data[:1] == bytes([_PERTURB_ID]):
            # the port carries the primary's frames in the order it sent them: the newest sample before the result
            # dates the result on the primary's clock, however late the laptop reads it
            self._acks.setdefault(msg.arbitration_id - _RESULT_BASE, self.clock())

    def _check_silence(self):
        quiet = time.monotonic() - self.last_frame
        if quiet > self.opts.silence_s:
            raise LinkError(
                f"no frames from the primary for {quiet:.1f} s (limit {self.opts.silence_s} s): "
                "port closed, primary reset or USB lost"
            )

    def pump(self, until_host: float) -> None:
        """Receive and log frames until host time `until_host` (never longer: recv has a timeout)."""
        while True:
            left = until_host - time.time()
            if left <= 0:
                return
            try:
                msg = self.bus.recv(timeout=min(0.05, left))
            except ValueError as e:  # python-can could not parse a line: counted (summary), keep going
                self.corrupt += 1
                self.report(f"corrupt SLCAN line skipped: {e}")
                continue
            except Exception as e:
                raise LinkError(f"connection to the primary lost: {type(e).__name__}: {e}") from e
            if msg is None:
                self._check_silence()
            else:
                self._take(msg)

    # ---- commands ------------------------------------------------------------
    def command(self, cells: Sequence[int], reg: str, values: dict, label: str, phase: str) -> dict:
        """Send reg to `cells`, wait for every CMD_RESULT (bounded); returns {cell: result name}."""
        try:
            res = self.client.command(list(cells), reg, **values)
        except Exception as e:
            raise LinkError(f"connection to the primary lost during {reg}: {type(e).__name__}: {e}") from e
        self.commands.append(
            {
                "phase": phase,
                "t_host": time.time(),
                "reg": reg,
                "values": dict(values),
                "label": label,
                "results": {int(j): r for j, r in sorted(res.items())},
            }
        )
        bad = {j: r for j, r in res.items() if r != "OK"}
        for j, r in sorted(bad.items()):
            self.failures.append({"phase": phase, "reg": reg, "label": label, "cell": int(j), "result": r})
        if bad:
            by: dict[str, list[int]] = {}
            for j, r in sorted(bad.items()):
                by.setdefault(r, []).append(j)
            self.report(
                f"{phase}: {reg} ({label}) failed: "
                + "; ".join(f"{r} from cell(s) {cells_text(js)}" for r, js in by.items())
            )
        self._check_silence()
        self.hook("command", reg=reg, phase=phase, results=res)
        return res

    def _setup(self, phase: str) -> list[int]:
        """Send the plan's setup commands; returns the cells that answered OK to all of them.

        A per-cell parameter is several commands of one register, each to the cells that take its value. k1 > k2
        must hold after every single write: a cell answering SHAPE to its new k1 (below its old k2) gets that k1
        again once the last k2 command has gone."""
        cells = self.plan.cells
        ok = set(cells)
        k1_shape: list[tuple[Command, list[int]]] = []  # (K1 command, cells that answered SHAPE)
        setup = self.plan.setup
        for i, c in enumerate(setup):
            res = self.command(list(c.cells) if c.cells else cells, c.reg, c.values, c.label, phase)
            if c.reg == "K1":
                shape = [j for j, r in res.items() if r == "SHAPE"]
                if shape:
                    k1_shape.append((c, shape))
                res = {j: r for j, r in res.items() if r != "SHAPE"}
            last_k2 = c.reg == "K2" and (i + 1 == len(setup) or setup[i + 1].reg != "K2")
            if last_k2 and k1_shape:
                for k1, shape in k1_shape:
                    again = self.command(shape, "K1", k1.values, k1.label + " (after k2)", phase)
                    fixed = {j for j, r in again.items() if r == "OK"}
                    self.failures = [
                        f
                        for f in self.failures
                        if not (
                            f["phase"] == phase and f["reg"] == "K1" and f["result"] == "SHAPE" and f["cell"] in fixed
                        )
                    ]
                    ok -= {j for j, r in again.items() if r != "OK"}
                k1_shape = []
            ok -= {j for j, r in res.items() if r != "OK"}
        return sorted(ok)

    def disable_all(self, phase: str, tries: int = 3) -> list[int]:
        """ENABLE off to every cell, retried for cells that do not answer OK; returns the unconfirmed cells."""
        left = list(self.plan.cells)
        for _ in range(tries):
            res = self.command(left, "ENABLE", {"on": 0}, "drive off", phase)
            left = [j for j in left if res.get(j) != "OK"]
            if not left:
                break
        return left

    def clock(self, dec: SampleDecoder | None = None) -> float | None:
        """Primary time (s) of the newest sample the decoder has seen, None before the first."""
        dec = dec or self.decoder
        return dec.t_s if dec.t_raw is not None else None

    def pump_primary(self, seconds: float, dec: SampleDecoder | None = None) -> None:
        """Log until the primary's clock advanced `seconds` (bounded: 3 x seconds + silence_s of wall time)."""
        dec = dec or self.decoder
        wall_end = time.time() + 3 * seconds + self.opts.silence_s
        start = self.clock(dec)
        while time.time() < wall_end:
            self.pump(time.time() + min(0.05, seconds))
            now = self.clock(dec)
            if start is None:
                start = now
            elif now is not None and now - start >= seconds:
                return

    # ---- identity ----------------------------------------------------------------
    def read_identity(self) -> dict:
        """Read every cell's IDENT block (firmware version, build, protocol map id) through the primary.

        Returns {cell: record}; a cell that did not send its block gets {"error": ...}. A map id that differs
        from this protocol definition's is reported (the cell would read our frames with another layout)."""
        try:
            info = self.client.info(list(self.plan.cells), blocks=("IDENT",))
        except Exception as e:
            raise LinkError(f"connection to the primary lost while reading identities: {type(e).__name__}: {e}") from e
        want = proto.map_id()
        out = {}
        for j in self.plan.cells:
            d = info.get(j, {})
            i = d.get("IDENT")
            if i is None:
                out[j] = {"error": "no IDENT block (" + ", ".join(d.get("results", [])) + ")"}
                continue
            out[j] = {
                "addr": i["addr"],
                "proto_version": i["tag"] >> 4,
                "fw_version": f"{i['fw_version'] >> 8}.{i['fw_version'] & 255}",
                "fw_version_raw": i["fw_version"],
                "build": f"0x{i['build']:08X}",
                "map_id": f"0x{i['map_id']:04X}",
                "map_id_matches": i["map_id"] == want,
            }
        bad = [j for j, r in out.items() if r.get("map_id_matches") is False]
        if bad:
            self.report(
                f"cell(s) {cells_text(bad)} report protocol map id "
                f"{', '.join(sorted({out[j]['map_id'] for j in bad}))}, this tool speaks 0x{want:04X}: "
                "reflash them (python -m metacell_tools.flash flash)"
            )
        self.identity = out
        self.hook("identity", identity=out)
        return out

    # ---- live plot -------------------------------------------------------------
    def _live(self, method: str, *args):
        """Call the live plot; a plotting error stops the plot (said once), never the run."""
        if self.live is None:
            return
        try:
            getattr(self.live, method)(*args)
        except Exception as e:  # noqa: BLE001 - the drive and the log matter more than the picture
            self.report(f"live plot stopped: {type(e).__name__}: {e}")
            self.live = None

    # ---- rest, zero ------------------------------------------------------------
    def _wait_still(self, repeat: Repeat, window_s: float = 0.5):
        """Log until every cell moved < 2 counts over `window_s` (bounded by rest_timeout_s); keep the angles."""
        dec = SampleDecoder(self.n_decode, report=lambda text: None)
        self.decoder = dec
        t_start = time.time()
        still = False
        while time.time() - t_start <= self.opts.rest_timeout_s:
            self.pump(time.time() + 0.1)
            s = series(tail_arrays(dec, window_s + 0.05), 0.0, None)
            if s is None or s.t.size < 3 or s.t[-1] - s.t[0] < 0.95 * window_s or not s.present.any():
                continue
            if is_steady(s.t, s.alpha[:, s.present], s.beta[:, s.present], settle_window_s=window_s):
                still = True
                break
        self.decoder = self.idle
        s = series(tail_arrays(dec, 1.0), 0.0, None)
        if s is not None:
            last = np.round(s.alpha[-1] / RAD_PER_COUNT), np.round(s.beta[-1] / RAD_PER_COUNT)
            repeat.rest_counts = {
                "still": still,
                "alpha": [int(v) if p else None for v, p in zip(last[0], s.present)],
                "beta": [int(v) if p else None for v, p in zip(last[1], s.present)],
            }
        else:
            repeat.rest_counts = {"still": False, "alpha": None, "beta": None}
        if not still:
            self.report(
                f"repeat {repeat.index}: lattice not still after {self.opts.rest_timeout_s} s; zeroing anyway "
                "(angles before zero kept in the summary)"
            )

    # ---- one repeat ------------------------------------------------------------
    def run_repeat(self, index: int) -> Repeat:
        rep = Repeat(index, SampleDecoder(self.n_decode, report=self.report))
        self.repeats.append(rep)
        phase = f"repeat {index}"
        if index > 1:
            self.report(f"{phase}: drive off, relaxing {self.opts.relax_s:g} s")
            self.pump_primary(self.opts.relax_s, self.idle)
        self._wait_still(rep)
        self.decoder = rep.decoder
        ok = self._setup(phase)
        if len(ok) < len(self.plan.cells) and not self.opts.keep_going:
            missing = sorted(set(self.plan.cells) - set(ok))
            rep.stopped = f"aborted: setup failed on cells {missing}"
            raise CommandFailed(
                f"{phase}: setup failed on cell(s) {cells_text(missing)} "
                "(see the failures in the summary; --keep-going runs without them)"
            )
        zero = self.command(ok, "ZERO", {}, "zero encoders", phase)
        ok = [j for j in ok if zero.get(j) == "OK"]
        en = self.command(ok, "ENABLE", {"on": 1}, "drive on", phase)
        rep.enabled_cells = [j for j in ok if en.get(j) == "OK"]
        rep.t0 = t0 = self.clock(rep.decoder)
        if t0 is None:
            raise LinkError(f"{phase}: no sample from any cell during the setup")
        # from here on rep.decoder has a time base: its t_s is the primary clock (self.clock never None)
        wall_limit = time.time() + 3 * self.plan.t_end_s + 30
        self.report(
            f"{phase}: drive enabled on {len(rep.enabled_cells)} cell(s); running up to {self.plan.t_end_s:g} s"
        )
        self.hook("enabled", repeat=index)
        self._live("begin", index, self.plan.t_end_s)
        pending = list(self.plan.perturbations)
        next_check = self.plan.last_perturbation_end_s + self.opts.settle_s
        rep.stopped = "t_end"
        while True:
            now = rep.decoder.t_s - t0
            if now >= self.plan.t_end_s:
                break
            if time.time() > wall_limit:  # frames arrive but the primary's clock hardly moves
                rep.stopped = "wall-time limit (primary clock too slow)"
                break
            due = [p for p in pending if p.start_s <= now]
            if due:
                pending = [p for p in pending if p.start_s > now]
                # one round of frames per identical payload: simultaneous pushes leave together
                groups: dict[tuple, list] = {}
                for p in due:
                    groups.setdefault(tuple(sorted(p.values.items())), []).append(p)
                for _, ps in groups.items():
                    sent = rep.decoder.t_s - t0
                    acks: dict[int, float | None] = {}
                    self._acks = acks
                    try:
                        res = self.command(
                            [p.cell for p in ps], "PERTURB", ps[0].values, "; ".join(p.label for p in ps), phase
                        )
                    finally:
                        self._acks = None
                    for p in ps:
                        ack = acks.get(p.cell)
                        rep.perturbations.append(
                            {
                                "label": p.label,
                                "cell": p.cell,
                                "chain": "alpha" if p.values.get("chain", 0) == 0 else "beta",
                                "planned_s": p.start_s,
                                "sent_s": sent,
                                "acked_s": None if ack is None else ack - t0,
                                "result": res.get(p.cell),
                            }
                        )
                continue
            if self.opts.early_stop and now >= next_check:
                next_check = now + 0.5
                s = series(tail_arrays(rep.decoder, self.opts.settle_s + 0.05), t0)
                if s is not None and s.present.any():
                    w = s.t >= s.t[-1] - self.opts.settle_s
                    if (
                        s.t[-1] - s.t[0] >= 0.95 * self.opts.settle_s
                        and w.sum() >= 3
                        and is_steady(
                            s.t[w],
                            s.alpha[w][:, s.present],
                            s.beta[w][:, s.present],
                            settle_window_s=self.opts.settle_s,
                        )
                    ):
                        rep.stopped = "steady"
                        break
            nxt = min(
                [self.plan.t_end_s] + [p.start_s for p in pending] + ([next_check] if self.opts.early_stop else [])
            )
            self.pump(time.time() + min(0.05, max(0.005, nxt - now)))
            self._live("poll", rep.decoder, rep.t0)
        rep.t_stop = t_stop = rep.decoder.t_s  # = self.clock(rep.decoder): the decoder has a time base since t0
        self._live("finish", rep.decoder, rep.t0)
        self.report(f"{phase}: stopped ({rep.stopped}) at t = {t_stop - t0:.2f} s")
        left = self.disable_all(phase)
        driving = [j for j in left if j in rep.enabled_cells]
        if driving:  # we switched these on and cannot switch them off: stop everything
            raise CommandFailed(f"{phase}: drive off not confirmed by cell(s) {cells_text(driving)} that were enabled")
        self.decoder = self.idle
        rep.decoder.save(self.out / f"repeat_{index:02d}", self._npz_attrs(rep))
        return rep

    def _npz_attrs(self, rep: Repeat) -> dict:
        return {
            "source": self.source,
            "repeat": rep.index,
            "capture": "experiment repeat (setup, run and drive-off)",
            "t_enable_primary_s": rep.t0,
            **({"topology": self.plan.topology} if self.plan.topology is not None else {}),
        }

    def run(self) -> None:
        self.read_identity()
        for k in range(1, self.opts.repeats + 1):
            self.run_repeat(k)

    def finish(self) -> list[int] | None:
        """Always: drive off on every cell (checked); stop the writers. Returns unconfirmed cells (None: link dead)."""
        self.decoder = self.idle
        try:
            left = self.disable_all("final drive off")
        except LinkError as e:
            self.report(
                f"SAFETY: could not send drive-off ({e}); the cells keep running their control loops: "
                "switch the 9 V motor supply off"
            )
            left = None
        else:
            if left:
                self.report(f"SAFETY: drive-off not confirmed by cell(s) {left}: switch the 9 V motor supply off")
        self.safe = left
        for rep in self.repeats:
            if rep.t0 is not None and rep.t_stop is None:
                rep.t_stop = t_stop = rep.decoder.t_s  # the decoder has a time base since t0
                rep.stopped = f"aborted at t = {t_stop - rep.t0:.2f} s"
                rep.decoder.save(self.out / f"repeat_{rep.index:02d}", self._npz_attrs(rep))
        for w in self.writers:
            w.stop()
        return left


# ---- decoded arrays -> time series ---------------------------------------------
def tail_arrays(dec: SampleDecoder, seconds: float) -> dict:
    """dec.arrays() of the rows of the last `seconds` of primary clock only.

    The live checks (steady, still) run every 0.1-0.5 s during a run: building the whole
    run's arrays each time grows without bound (0.3 s per 32k rows) and a reader that
    stalls lets the primary's queue overflow. The rows are in arrival order."""
    rows = dec.rows
    i = len(rows)
    if i:
        since = rows[-1][3] - seconds
        seg = rows[-1][0]
        while i > 0 and rows[i - 1][3] >= since and rows[i - 1][0] == seg:
            i -= 1
    tmp = SampleDecoder(n_cells=dec.n, report=lambda text: None)
    tmp.rows = rows[i:]
    return tmp.arrays()


@dataclass
class Series:
    t: np.ndarray  # (T,) s after the drive was enabled
    alpha: np.ndarray  # (T, N) rad, held over missing samples
    beta: np.ndarray
    present: np.ndarray  # (N,) bool: cell has at least one sample
    held: np.ndarray  # (N,) samples filled by holding the previous value


def series(arr: dict, t0: float, t_min: float | None = 0.0, t_max: float | None = None) -> Series | None:
    """SampleDecoder.arrays() -> uniform-in-row time series for t_min <= t <= t_max (None if no rows).

    Row time: mean primary clock of the row's samples (one poll cycle), t = mean(t_s) - t0,
    t0 on the same clock (the decoder's t_s at the enable). Missing samples of a present cell hold
    the previous value (the first one: the next value); absent cells are zeros, flagged in
    `present`. Rows that do not advance in time are dropped."""
    ts = arr["t_s"]
    if ts.shape[0] == 0 or np.all(np.isnan(ts)):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        t = np.nanmean(ts, axis=1) - t0
    keep = (
        np.isfinite(t) & (t >= (-math.inf if t_min is None else t_min)) & (t <= (math.inf if t_max is None else t_max))
    )
    t = t[keep]
    a, b = arr["alpha_counts"][keep], arr["beta_counts"][keep]
    if t.size == 0:
        return None
    mono = np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])
    t, a, b = t[mono], a[mono], b[mono]
    present = ~np.all(np.isnan(a), axis=0)
    held = np.isnan(a).sum(axis=0) * present

    def fill(x):
        x = x.copy()
        for j in range(x.shape[1]):
            col = x[:, j]
            ok = ~np.isnan(col)
            if not ok.any():
                col[:] = 0.0
                continue
            idx = np.where(ok, np.arange(col.size), 0)
            np.maximum.accumulate(idx, out=idx)
            first = int(np.argmax(ok))
            idx[:first] = first
            x[:, j] = col[idx]
        return x

    return Series(t, fill(a) * RAD_PER_COUNT, fill(b) * RAD_PER_COUNT, present, held.astype(int))


STEADY_TOL_RAD = DEFAULT_TOL_RAD
