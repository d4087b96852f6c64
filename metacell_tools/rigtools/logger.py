"""Rig logger on python-can: log files, decoded alpha_j(t)/beta_j(t) arrays (NPZ, CSV), gap reports, reconnects.

    python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run1 --duration 60
    python -m metacell_tools.rigtools.logger -c /dev/pts/3@115200 -o out/emu --formats asc,blf

Writes <out>.<fmt> for every python-can format asked for (asc blf csv db log trc txt),
<out>.csv (one row per cell sample, on disk within 1.5 s of its frame) and, at the end,
<out>.npz (the one run layout host_emulator.load reads, time x cell with a `partial` flag
per cycle; written to a temporary name and renamed; see docs/datapath.md).
`--repair PREFIX` puts the files of a killed or full-disk run right (BLF cut to its last
object, NPZ rebuilt from the CSV). A port another program holds is refused. Every gap in a cell's
sequence counter is reported on stderr with its length as it happens and kept in the NPZ;
a link silent for more than a second is reported; a lost connection is reported, retried
every second, and logged as a new segment. --duration counts from the first frame.

Ctrl-C, SIGTERM and SIGHUP end the run in order (files complete, exit 0); a full disk
ends it with a one-line error and files readable up to the last complete record.
Exit codes: 0 ok, 2 bad input (arguments, output path), 3 run failed (port cannot be
opened, no frame arrives, write error).
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import struct
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import can
import numpy as np

from protocol.codec import RAD_PER_COUNT

from . import proto

T128_S = 128e-6
T_WRAP = 1 << 16  # the frames' time field wraps every 65536 x 128 us = 8.39 s
CSV_HEADER = "segment,cycle,cell,t_s,host_time,alpha_counts,beta_counts,flags\n"
TEXT_FORMATS = ("asc", "csv", "log", "txt", "trc")


class RunFailed(Exception):
    """The run could not go on (exit 3); the message is one line."""


def reset_cause_names(bits: int) -> list[str]:
    """Names of the RESET_CAUSE bits set in a BOOT.reset_cause / PRIMARY_HEALTH.reset_cause byte."""
    return [name for name, b in sorted(proto.D.RESET_CAUSE.items(), key=lambda kv: kv[1]) if bits >> b & 1]


class SampleDecoder:
    """CELL_SAMPLE frames -> per-cycle rows; gaps from the per-cell sequence counters.

    Time: every sample carries the primary's microsecond clock in 128 us units, modulo
    2^16 (8.39 s). Frames arrive in order, so each sample's time is unwrapped forward
    from the previous one (never backwards). A gap longer than 8.39 s (a stalled reader
    whose frames were dropped) would be ambiguous from that field alone: the primary's
    heartbeat (PRIMARY_STATUS, once a second) carries its 32-bit millisecond clock, and
    decoded rows are held until the next heartbeat confirms their time base; a mismatch
    of whole wrap periods is put right at the largest time step among the held rows.

    Cycles: a cell's 8-bit sequence counter names its poll cycle modulo 256; the number
    of cycles between two samples of a cell is unwrapped with the elapsed (unwrapped)
    time over the measured cycle period, so no stall length can make a cycle number
    repeat or go backwards. A reconnect starts a new segment, whose time continues from
    the previous one by the host clock's elapsed time.

    `sink(rows)` receives finished rows in time order; without a sink they are kept in
    `self.rows` (tests, small runs). With hold=False (the default, for live use such as the
    experiment runner) every row is finished at once and a heartbeat correction applies
    from the next row on; the logger holds rows (hold=True)."""

    HOLD_ROWS = 8192  # rows held at most while waiting for a heartbeat
    HOLD_S = 1.25  # ... and at most this long (host clock): the 1 Hz heartbeat plus a margin, heartbeat or not

    def __init__(
        self,
        n_cells: int = proto.N_CELLS,
        report: Callable[[str], None] | None = None,
        sink: Callable[[list[tuple]], None] | None = None,
        hold: bool = False,
    ) -> None:
        self.n = n_cells
        self.hold = hold
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.db = proto.database()
        self.rows: list[tuple] = []  # (segment, cycle, cell, t_s, host, alpha, beta, flags) without a sink
        self.sink = sink or self.rows.extend
        self.gaps: list[tuple[int, int, int, int]] = []  # (segment, cell, first missing cycle, missing count)
        self.status: dict[tuple[str, int | None], dict] = {}  # (frame kind, cell) -> last decoded dict
        self.events: list[tuple[float, str]] = []  # (host time, text)
        self.segment = 0
        self.n_rows = 0
        self.t_end = 0.0  # t_s of the last row
        self.host_end: float | None = None  # host time of the last row
        self.t_base = 0.0  # t_s of the segment's time zero
        self.per: float | None = None  # cycle period (128 us units), measured
        self.tx_drop = 0
        self.usb_lost = 0  # bytes the primary's USB port did not take (PRIMARY_HEALTH, cumulative)
        self.primary_reset_cause: list[str] | None = None  # PRIMARY_HEALTH.reset_cause, names
        self._reset()

    def _reset(self):
        self.u_last: int | None = None  # unwrapped time of the newest sample (128 us units)
        self.t_raw: int | None = None  # its raw 16-bit time field
        self.u0 = 0  # unwrapped time of the segment's first sample (set with it)
        self.host0: float | None = None  # host time of the segment's first sample
        # (heartbeat time in 128 us units, host time) awaiting the next sample
        self.pending_hb: tuple[float, float | None] | None = None
        self.off_min: float | None = None  # min(host - primary time) over confirmed samples, s
        self.hb_off: float | None = None  # unwrapped time - heartbeat time (128 us units)
        self.held: list[list[Any]] = []  # [cell, seq, u, host, alpha, beta, flags]
        self.prev: list[tuple[int, int] | None] = [None] * self.n  # (cycle, u) of each cell's last row
        self.k_ref: int | None = None

    def new_segment(self, host: float, why: str) -> None:
        self.finish()
        self.events.append((host, why))
        self.report(f"segment {self.segment + 1}: {why}")
        self.segment += 1
        if self.host_end is not None:
            self.t_base = self.t_end + max(0.0, host - self.host_end)
        else:
            self.t_base = self.t_end
        self._reset()

    def feed(self, msg: can.Message) -> None:
        kind, j = proto.frame_kind(msg.arbitration_id)
        if kind == "UNKNOWN" or msg.is_extended_id or msg.is_remote_frame:
            return
        if kind == "CELL_SAMPLE" and j is not None:  # a per-cell frame
            try:
                d = self.db.decode_message(
                    msg.arbitration_id, bytes(msg.data), decode_choices=False, scaling=False
                )  # raw wire integers: counts, 128 us ticks
            except Exception as e:
                self.report(f"undecodable CELL_SAMPLE frame 0x{msg.arbitration_id:03X}: {e}")
                return
            self.sample(j, d["seq"], d["alpha"], d["beta"], d["t128"], d["flags"], msg.timestamp)
        elif kind in ("CELL_STATUS", "CELL_LINK", "PRIMARY_STATUS", "PRIMARY_REJECT", "CMD_RESULT", "PRIMARY_HEALTH"):
            try:
                d = self.db.decode_message(msg.arbitration_id, bytes(msg.data), decode_choices=False)
            except Exception as e:  # wrong length etc.: keep going, say so
                self.report(f"undecodable {kind} frame 0x{msg.arbitration_id:03X}: {e}")
                return
            self.status[(kind, j)] = d
            if kind == "PRIMARY_STATUS":
                self.heartbeat(round(d["uptime_ms"] * 1000), d["tx_drop"], msg.timestamp)
            elif kind == "PRIMARY_HEALTH":
                self.health(int(d["reset_cause"]), int(d["usb_lost"]))

    def sample(self, j: int, seq: int, alpha: int, beta: int, t128: int, flags: int, host: float) -> None:
        t128 = int(t128) % T_WRAP
        if self.u_last is None:
            u = t128
            self.u0 = u
            self.host0 = float(host)
            self.off_min = self.host0 - u * T128_S
        else:
            u = self.u_last + ((t128 - self.u_last) % T_WRAP)
        self.u_last = u
        self.t_raw = t128
        self.held.append([j, int(seq) & 0xFF, u, float(host), alpha, beta, flags])
        if self.pending_hb is not None:
            self._apply_hb()
        if not self.hold or len(self.held) >= self.HOLD_ROWS:
            self.flush()

    @property
    def t_s(self) -> float:
        """t_s of the newest sample (primary clock, s)."""
        if self.u_last is None:
            return self.t_end
        return self.t_base + (self.u_last - self.u0) * T128_S

    def health(self, reset_cause: int, usb_lost: int) -> None:
        """PRIMARY_HEALTH: say why the primary last restarted (once) and every growth of the bytes its USB port
        did not take (the laptop stopped reading for longer than the port's 70 ms send timeout)."""
        names = reset_cause_names(reset_cause)
        if names != self.primary_reset_cause:
            self.primary_reset_cause = names
            warn = " (it hung: watchdog reset)" if "WDT" in names else ""
            self.report(f"primary: last reset {'+'.join(names) or 'none'}{warn}")
        if usb_lost != self.usb_lost:
            if usb_lost > self.usb_lost:
                self.report(
                    f"primary: {usb_lost - self.usb_lost} bytes of output lost at its USB port "
                    f"({usb_lost} since boot; the reader stalled)"
                )
            self.usb_lost = usb_lost

    def heartbeat(self, uptime_ms: int, tx_drop: int = 0, host: float | None = None):
        """The primary's millisecond clock: confirms (or puts right) the held rows' time base at the
        next sample (a heartbeat may be the first frame after a gap: its time is compared with the
        sample that follows it, never with the one before)."""
        if tx_drop != self.tx_drop:
            if tx_drop > self.tx_drop:
                self.report(
                    f"primary: {tx_drop}{'+' if tx_drop == 255 else ''} frames dropped at its USB queue "
                    "(the reader fell behind)"
                )
            self.tx_drop = tx_drop
        self.pending_hb = (uptime_ms * 1000 / 128, host)

    def _apply_hb(self):
        # called by sample() only, after it has set u_last, with a heartbeat pending
        assert self.pending_hb is not None and self.u_last is not None
        hb, host = self.pending_hb
        self.pending_hb = None
        if self.hb_off is None:
            # first heartbeat of the segment: the host clock since the last confirmed sample
            # tells the primary time elapsed (both frames read without a backlog)
            self._host_check(host)
            self.hb_off = self.u_last - hb
        else:
            miss = round((hb + self.hb_off - self.u_last) / T_WRAP)
            if miss > 0:
                self._rewrap(miss * T_WRAP)
        self.flush()

    def _rewrap(self, du: int, evidence: bool = False):
        """Add du to every held row from the one where the frames were lost: the row whose cell's
        cycle-counter step fits its time step worst (a lost wrap shows there as a cycle step that
        the time step does not explain); the largest time step if that is ambiguous."""
        assert self.u_last is not None  # a correction needs a sample to correct
        last = {j + 1: (p[0] & 0xFF, p[1]) for j, p in enumerate(self.prev) if p is not None}
        steps = []  # (row index, cycle step modulo 256, time step) per held row
        for i, (j, seq, u, *_rest) in enumerate(self.held):
            if j in last:
                steps.append((i, (seq - last[j][0]) % 256, u - last[j][1]))
            last[j] = (seq, u)
        if not steps:
            if not evidence:
                self.u_last += du  # nothing held: the rows from now on carry the correction
                self.report(
                    f"time base: {du * T128_S:.2f} s more elapsed than the frames' 8.4 s time field "
                    "shows (from the next sample on)"
                )
            return
        per = self.per
        if per is None:
            est = [dt / c for _, c, dt in steps if 1 <= c <= 3 and dt > 0]
            per = float(np.median(est)) if est else None
        scores = []
        for i, c, dt in steps:
            if per:
                r = dt / per - c
                scores.append((abs(r - 256 * round(r / 256)), i))
            else:
                scores.append((dt, i))
        best = max(sc for sc, _ in scores)
        if evidence and (not per or best < 4):
            return  # the host clock alone is no proof (the rows may be an old backlog)
        # every cell shows the jump at its first row after it: cut at the earliest of those
        at = min(i for sc, i in scores if sc >= (min(best, max(4.0, best / 2)) if per else best))
        for r in self.held[at:]:
            r[2] += du
        self.u_last += du
        self.report(
            f"time base: {du * T128_S:.2f} s more elapsed in a gap than the frames' 8.4 s time field shows "
            f"(put right from the {'host' if evidence else 'primary heartbeat'} clock)"
        )

    def _host_check(self, host_now: float | None):
        """Whole wrap periods the held rows miss by the host clock (anchored on the least-delayed sample)."""
        if self.off_min is None or not host_now or self.u_last is None:
            return
        miss = round(((host_now - self.off_min) / T128_S - self.u_last) / T_WRAP)
        if miss > 0:
            self._rewrap(miss * T_WRAP, evidence=True)

    def tick(self, host_now: float) -> None:
        """Called by the receive loop (also while no frame arrives): rows held longer than HOLD_S are checked
        against the host clock and finished, so no row waits on a heartbeat that does not come."""
        if self.hold and self.held and host_now - self.held[0][3] >= self.HOLD_S:
            self.finish()

    def finish(self) -> None:
        """End of the stream: rows after the last heartbeat are checked against the host clock, then flushed."""
        if self.held:
            self._host_check(self.held[-1][3])
        self.flush()

    def prev_u_any(self) -> int | None:
        us = [p[1] for p in self.prev if p is not None]
        return max(us) if us else None

    def flush(self) -> None:
        """Assign cycles to the held rows, report gaps, hand the rows to the sink."""
        if not self.held:
            return
        out = []
        for j, seq, u, host, al, be, fl in self.held:
            prev = self.prev[j - 1]
            if prev is None:
                if self.k_ref is None:
                    k = seq
                else:
                    k = self.k_ref + ((seq - self.k_ref + 128) % 256) - 128
            else:
                pk, pu = prev
                base = (seq - pk) % 256
                if self.per:
                    m = max(0, round(((u - pu) / self.per - base) / 256))
                else:
                    m = 0
                d = base + 256 * m
                if d == 0 and u > pu:
                    d = 256  # time went on: a whole wrap of the counter, not a repeat
                if d == 0:
                    self.report(f"cell {j}: cycle {pk} again (duplicate frame), skipped")
                    continue
                if d <= 3 and u > pu:
                    per = (u - pu) / d
                    self.per = per if self.per is None else 0.9 * self.per + 0.1 * per
                k = pk + d
                if d > 1:
                    self.gaps.append((self.segment, j, pk + 1, d - 1))
                    self.report(
                        f"gap: cell {j} lost {d - 1} sample(s) ({(u - pu) * T128_S:.3f} s) after cycle {pk} "
                        f"(segment {self.segment})"
                    )
            self.prev[j - 1] = (k, u)
            off = host - u * T128_S  # host clock minus primary clock (+ the read latency)
            if self.off_min is None or off < self.off_min:
                self.off_min = off  # the least-delayed confirmed sample anchors the host check
            self.k_ref = k if self.k_ref is None else max(self.k_ref, k)
            t_s = self.t_base + (u - self.u0) * T128_S
            out.append((self.segment, k, j, t_s, host, al, be, fl))
        self.held = []
        if out:
            self.t_end = out[-1][3]
            self.host_end = out[-1][4]
            self.n_rows += len(out)
            self.sink(out)

    def arrays(self) -> dict:
        """Cycle x cell arrays (NaN / -1 where a cell has no sample) of the rows kept in memory."""
        self.finish()
        return rows_to_arrays(np.array(self.rows, dtype=np.float64).reshape(-1, 8), self.n, self.gaps)

    def save(self, prefix: Path, attrs: dict | None = None) -> list[Path]:
        """<prefix>.npz in the one run layout (host_emulator.workbench.datasets; attrs: source, ...), <prefix>.csv."""
        prefix = Path(prefix)
        prefix.parent.mkdir(parents=True, exist_ok=True)
        arr = self.arrays()
        npz = write_capture(prefix.with_suffix(".npz"), arr, attrs or {})
        csv = prefix.with_suffix(".csv")
        with open(csv, "w") as f:
            f.write(CSV_HEADER)
            f.write(format_rows(self.rows))
        return [npz, csv]


def write_capture(path: Path, arr: dict, attrs: dict) -> Path:
    """Cycle x cell arrays (rows_to_arrays) as an NPZ in the one run layout of host_emulator.workbench.datasets:
    time from the first sample, alpha/beta in rad (NaN: no sample), flags, counts, each cell's primary clock, host
    time, cycles, segments, partial cycles, gaps; attrs (source, capture, channel, ...) with units and provenance;
    written to a temporary name and renamed (datasets.save_npz_atomic). he.load reads it."""
    from host_emulator.provenance import provenance
    from host_emulator.workbench.datasets import logger_layout, write_npz

    lay = logger_layout(arr)
    meta = {"source": "unknown", **attrs, "t_origin_s": lay.pop("t_origin_s")}
    meta.update({f"provenance.{k}": v for k, v in provenance().items()})
    return write_npz(path, lay, meta)


def format_rows(rows: Iterable[tuple]) -> str:
    return "".join(f"{seg},{k},{j},{ts:.6f},{host:.6f},{al},{be},{fl}\n" for seg, k, j, ts, host, al, be, fl in rows)


def rows_to_arrays(rows: np.ndarray, n: int, gaps: list[tuple[int, int, int, int]]) -> dict:
    """Cycle x cell arrays from an (m, 8) row table (segment, cycle, cell, t_s, host, alpha, beta, flags)."""
    seg_cyc = rows[:, :2].astype(np.int64)
    if len(rows):
        keys, inv = np.unique(seg_cyc, axis=0, return_inverse=True)
    else:
        keys, inv = np.zeros((0, 2), np.int64), np.zeros(0, np.intp)
    m = len(keys)
    a = np.full((m, n), np.nan)
    b = np.full((m, n), np.nan)
    t = np.full((m, n), np.nan)
    h = np.full((m, n), np.nan)
    fl = np.full((m, n), -1, dtype=np.int16)
    if len(rows):
        inv = inv.reshape(-1)
        col = rows[:, 2].astype(np.int64) - 1
        a[inv, col], b[inv, col], t[inv, col], h[inv, col] = rows[:, 5], rows[:, 6], rows[:, 3], rows[:, 4]
        fl[inv, col] = rows[:, 7].astype(np.int16)
    return {
        "segment": keys[:, 0],
        "cycle": keys[:, 1],
        "partial": partial_cycles(keys[:, 0], a),
        "cells": np.arange(1, n + 1),
        "t_s": t,
        "host_time": h,
        "alpha_counts": a,
        "beta_counts": b,
        "alpha_rad": a * RAD_PER_COUNT,
        "beta_rad": b * RAD_PER_COUNT,
        "flags": fl,
        "gaps": np.array(gaps, dtype=np.int64).reshape(-1, 4),
    }


def partial_cycles(segment: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Per cycle: True where logging started or stopped inside it, i.e. some cell's sample lies before that cell's
    first or after its last sample of the segment (the first and last cycles of a run or a reconnect, NaN for the
    cells polled outside the log). Gaps inside a cell's span are not partial: they are in `gaps`."""
    m, n = alpha.shape
    out = np.zeros(m, dtype=bool)
    have = ~np.isnan(alpha)
    for s in np.unique(segment):
        rows = np.nonzero(segment == s)[0]
        h = have[rows]
        seen = h.any(axis=0)
        if not seen.any():
            continue
        idx = np.arange(len(rows))[:, None]
        first = np.where(seen, h.argmax(axis=0), 0)
        last = np.where(seen, len(rows) - 1 - h[::-1].argmax(axis=0), -1)
        edge = seen & ~h & ((idx < first) | (idx > last))
        out[rows] = edge.any(axis=1)
    return out


class CsvChunks:
    """Rows streamed to <out>.csv in chunks: memory stays bounded, and a chunk is written (to the OS) once it holds
    CHUNK rows or its oldest row has waited FLUSH_S (tick() is called by the receive loop, frames or not), so a
    killed logger loses only the rows of the last FLUSH_S plus those still held for a heartbeat (HOLD_S)."""

    CHUNK = 2048
    FLUSH_S = 0.25

    def __init__(self, path: Path) -> None:
        self.path = path
        self.f = open(path, "w")
        self.f.write(CSV_HEADER)
        self.f.flush()
        self.buf: list[tuple] = []
        self.since: float | None = None  # monotonic time the oldest buffered row arrived here

    def __call__(self, rows):
        if rows and not self.buf:
            self.since = time.monotonic()
        self.buf.extend(rows)
        if len(self.buf) >= self.CHUNK:
            self.write()

    def tick(self) -> None:
        if self.buf and self.since is not None and time.monotonic() - self.since >= self.FLUSH_S:
            self.write()

    def write(self) -> None:
        if self.buf:
            text = format_rows(self.buf)
            self.buf = []
            self.since = None
            self.f.write(text)
            self.f.flush()

    def close(self) -> None:
        try:
            self.write()
        finally:
            try:
                self.f.close()
            except OSError:
                pass


def read_rows(csv: Path) -> np.ndarray:
    """The row table of a streamed CSV (complete lines only)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    return rows.reshape(-1, 8)


def truncate_to_last_line(path: Path) -> None:
    """Cut a text log after its last complete line (a write error may leave half a line)."""
    try:
        size = path.stat().st_size
        with open(path, "rb+") as f:
            back = min(size, 4096)
            while back:
                f.seek(size - back)
                tail = f.read(back)
                i = tail.rfind(b"\n")
                if i >= 0:
                    f.truncate(size - back + i + 1)
                    return
                if back == size:
                    break
                back = min(size, back * 2)
            f.truncate(0)
    except OSError:
        pass


def flush_writer(w) -> None:
    """Push a python-can writer's buffered data to the OS: BLF's pending container (a private method of
    BLFWriter, guarded), then the file object. Errors surface at stop()."""
    try:
        if hasattr(w, "_flush") and type(w).__name__ == "BLFWriter":
            w._flush()
        f = getattr(w, "file", None)
        if f is not None and not f.closed:
            f.flush()
    except (OSError, ValueError):
        pass  # reported by stop() at the end


BLF_HEADER = 144  # python-can's FILE_HEADER_SIZE
BLF_OBJ = struct.Struct("<4sHHLL")  # signature "LOBJ", header size, version, object size, type


def repair_blf(path: Path) -> tuple[int, int] | None:
    """Truncate a BLF to its last complete object and rewrite its header so python-can's BLFReader reads it
    (a killed logger leaves a cut container, or a file shorter than its header). Returns (bytes before, after)
    when it changed the file, None when the file was sound or absent."""
    try:
        size = path.stat().st_size
    except OSError:
        return None
    from can.io.blf import FILE_HEADER_STRUCT

    with open(path, "rb+") as f:
        head = f.read(BLF_HEADER)
        if len(head) < BLF_HEADER or head[:4] != b"LOGG":
            f.seek(0)
            f.truncate(0)
            _blf_header(f, None, BLF_HEADER)
            return size, BLF_HEADER
        pos = BLF_HEADER
        while pos + BLF_OBJ.size <= size:
            f.seek(pos)
            sig, _, _, obj_size, _ = BLF_OBJ.unpack(f.read(BLF_OBJ.size))
            end = pos + obj_size + obj_size % 4
            if sig != b"LOBJ" or obj_size < BLF_OBJ.size or end > size:
                break
            pos = end
        header = FILE_HEADER_STRUCT.unpack(head[: FILE_HEADER_STRUCT.size])
        if pos == size and header[10] == size:
            return None
        f.truncate(pos)
        _blf_header(f, header, pos)
    return size, pos


def _blf_header(f, header, filesize: int) -> None:
    from can.io.blf import FILE_HEADER_STRUCT

    if header is None:  # python-can's defaults (BLFWriter._write_header) with no objects
        fields = [b"LOGG", BLF_HEADER, 5, 0, 0, 0, 2, 6, 8, 1, filesize, BLF_HEADER, 0, 0] + [0] * 16
    else:
        fields = list(header)
        fields[10] = filesize
    f.seek(0)
    f.write(FILE_HEADER_STRUCT.pack(*fields))
    f.write(b"\x00" * (BLF_HEADER - FILE_HEADER_STRUCT.size))


def gaps_from_rows(rows: np.ndarray) -> list[tuple[int, int, int, int]]:
    """(segment, cell, first missing cycle, count) from a row table alone: the gaps a CSV shows (--repair)."""
    gaps: list[tuple[int, int, int, int]] = []
    if not len(rows):
        return gaps
    seg, cyc, cell = (rows[:, i].astype(np.int64) for i in range(3))
    order = np.lexsort((cyc, cell, seg))
    seg, cyc, cell = seg[order], cyc[order], cell[order]
    same = (seg[1:] == seg[:-1]) & (cell[1:] == cell[:-1])
    step = cyc[1:] - cyc[:-1]
    for i in np.nonzero(same & (step > 1))[0]:
        gaps.append((int(seg[i]), int(cell[i]), int(cyc[i] + 1), int(step[i] - 1)))
    return sorted(gaps)


def repair(
    prefix: Path,
    n_cells: int = proto.N_CELLS,
    report: Callable[[str], None] | None = None,
    source: str | None = None,
) -> dict:
    """After a crash, a kill or a full disk: cut the text logs (and the CSV) after their last complete line, cut the
    BLF after its last complete object, and rebuild <prefix>.npz from the CSV (gaps from the cycle counters) in the
    one run layout (write_capture), labelled source (default unknown: the CSV does not say what sent the frames).
    Returns the logger's cycle x cell arrays the NPZ was made from."""
    report = report or (lambda text: print(text, file=sys.stderr, flush=True))
    prefix = Path(prefix)
    csv = prefix.with_suffix(".csv")
    if not csv.is_file():
        raise RunFailed(f"--repair {prefix}: {csv} not found (the logger's CSV is what the NPZ is rebuilt from)")
    for f in TEXT_FORMATS:
        p = prefix.with_suffix("." + f)
        if p.is_file():
            truncate_to_last_line(p)
    blf = repair_blf(prefix.with_suffix(".blf"))
    if blf:
        report(f"{prefix.with_suffix('.blf')}: cut from {blf[0]} to {blf[1]} bytes (last complete object)")
    try:
        rows = read_rows(csv)
    except ValueError as e:
        raise RunFailed(f"--repair {prefix}: {csv} is not the logger's CSV: {e}") from None
    arrays = rows_to_arrays(rows, n_cells, gaps_from_rows(rows))
    attrs = {"source": source or "unknown", "capture": "rigtools logger, rebuilt from the CSV by --repair"}
    if not source:
        attrs["source_note"] = "the CSV does not say whether a rig or an emulator sent it (--source LABEL)"
    write_capture(prefix.with_suffix(".npz"), arrays, attrs)
    stale = prefix.with_name(prefix.name + ".npz.tmp")
    if stale.exists():
        stale.unlink()
    return arrays


class RigLogger:
    """Receive loop with python-can writers, decoding, chunked CSV and reconnect."""

    SILENT_S = 1.0

    def __init__(
        self,
        interface: str,
        channel: str,
        prefix: Path,
        formats: Sequence[str] = ("asc",),
        bitrate: int | None = None,
        reconnect_s: float = 1.0,
        give_up_s: float | None = None,
        report: Callable[[str], None] | None = None,
        open_bus: Callable[[], can.BusABC] | None = None,
        first_frame_s: float = 30.0,
        wait_open_s: float = 0.0,
        source: str | None = None,
    ) -> None:
        self.interface, self.channel, self.bitrate = interface, channel, bitrate
        self.source = source or channel_source(interface, channel)  # written into the NPZ: rig, emulator or unknown
        self.prefix = Path(prefix)
        self.formats = [f.strip().lstrip(".") for f in formats if f.strip()]
        self.reconnect_s, self.give_up_s = reconnect_s, give_up_s
        self.first_frame_s, self.wait_open_s = first_frame_s, wait_open_s
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.csv: CsvChunks | None = None
        self.decoder = SampleDecoder(report=self.report, hold=True)
        self.open_bus = open_bus or self._open
        self.frames = 0
        self.reconnects = 0
        self.corrupt = 0
        self.commands: list[tuple[float, str]] = []  # (seconds after the first frame, command-tool arguments)
        self.command_log: list[tuple[float, str, dict]] = []  # (seconds, command, {cell: result})
        self.stop_reason: str | None = None  # set by a signal handler
        self.error: str | None = None
        self._flushed = 0.0
        self._watched = 0.0
        self.others: set[int] = set()  # pids of other programs seen holding the port while logging

    def _open(self):
        from .slcanbus import open_bus

        # python-can's own reader when a bit rate is sent (as before); either way the port is claimed (portlock)
        return open_bus(self.interface, self.channel, plain=bool(self.bitrate), bitrate=self.bitrate or None)

    def _connect(self, deadline, first: bool):
        t0 = time.time()
        limit = self.wait_open_s if first else self.give_up_s
        while True:
            try:
                return self.open_bus()
            except Exception as e:  # python-can and pyserial raise several types
                text = str(e).splitlines()[0] if str(e) else type(e).__name__
                if limit is not None and time.time() - t0 >= limit:
                    raise RunFailed(f"cannot open {self.channel}: {text}") from None
                if (deadline is not None and time.time() >= deadline) or self.stop_reason:
                    return None
                self.report(f"cannot open {self.channel}: {text}; retrying in {self.reconnect_s} s")
                time.sleep(self.reconnect_s)

    def _take(self, msg, writers):
        self.frames += 1
        for w in writers:
            w.on_message_received(msg)
        self.decoder.feed(msg)

    def _due_commands(self, bus, writers, t_start):
        """Run scheduled commands (--do T:COMMAND) through the same port: one program owns a serial port."""
        from .command import RigClient, build, parser

        while self.commands and self.commands[0][0] <= time.time() - t_start:
            t, text = self.commands.pop(0)
            args = parser().parse_args(["-c", "-"] + text.split())
            reg, values = build(args)
            client = RigClient(bus, on_message=lambda m: self._take(m, writers))
            res = client.command(args.cells, reg, **values)
            self.command_log.append((t, text, res))
            self.report(f"t={t:g} s: {text} -> " + ", ".join(f"{j}:{r}" for j, r in sorted(res.items())))

    WRITERS_FLUSH_S = 1.0

    def _tick(self, now: float, csv: CsvChunks, writers) -> None:
        """Bounded latency to disk, frames or not: held rows (HOLD_S) and the CSV chunk (FLUSH_S), and once a second
        the log writers' buffers (BLF: its pending container), so a killed logger leaves little unwritten."""
        self.decoder.tick(now)
        csv.tick()
        if now - self._flushed >= self.WRITERS_FLUSH_S:
            self._flushed = now
            for w in writers:
                flush_writer(w)
        if now - self._watched >= self.WATCH_S:
            self._watched = now
            self._watch_port()

    WATCH_S = 2.0

    def _watch_port(self) -> None:
        """A program that opens the port after us (python-can's own logger takes no lock) splits the bytes with us:
        say so once per program, and count it in the summary line."""
        from .portlock import device_of, holders

        dev = device_of(self.channel) if self.interface == "slcan" else None
        if dev is None:
            return
        new = {pid: cmd for pid, cmd in holders(dev).items() if pid not in self.others}
        for pid, cmd in new.items():
            self.others.add(pid)
            self.report(f"another program opened {dev} (pid {pid}: {cmd}): both lose samples (one reader per port)")

    def _on_signal(self, signum, frame):
        self.stop_reason = signal.Signals(signum).name

    def run(self, duration: float | None = None) -> int:
        import can

        self.prefix.parent.mkdir(parents=True, exist_ok=True)
        csv = self.csv = CsvChunks(self.prefix.with_suffix(".csv"))
        self.decoder.sink = csv
        writers = []
        old = {}
        for s in (signal.SIGTERM, signal.SIGHUP):
            try:
                old[s] = signal.signal(s, self._on_signal)
            except ValueError:  # not the main thread (tests): no handlers
                pass
        bus = None
        try:
            writers = [can.Logger(str(self.prefix.with_suffix("." + f))) for f in self.formats if f != "csv"]
            started = time.time()
            bus = self._connect(None if duration is None else started + duration + self.first_frame_s, True)
            t_first = None
            deadline = None
            last_rx = time.time()
            silent = False
            while bus is not None and not self.stop_reason:
                now = time.time()
                self._tick(now, csv, writers)
                if deadline is not None and now >= deadline:
                    break
                if t_first is None and self.first_frame_s is not None and now - started > self.first_frame_s:
                    raise RunFailed(
                        f"no frame from {self.channel} in {self.first_frame_s:g} s "
                        "(is the primary connected and the channel right?)"
                    )
                if t_first is not None:
                    self._due_commands(bus, writers, t_first)
                try:
                    msg = bus.recv(timeout=0.2)
                except ValueError as e:
                    # python-can could not parse a line (e.g. bytes lost on the port): the line is gone, go on
                    self.corrupt += 1
                    self.report(f"corrupt SLCAN line skipped: {e}")
                    continue
                except Exception as e:
                    lost = time.time()
                    self.report(f"connection lost: {str(e).splitlines()[0] if str(e) else type(e).__name__}")
                    try:
                        bus.shutdown()
                    except Exception:
                        pass
                    bus = self._connect(deadline, False)
                    if bus is None:
                        break
                    self.reconnects += 1
                    self.decoder.new_segment(
                        time.time(), f"reconnected after {time.time() - lost:.1f} s (samples in between are lost)"
                    )
                    last_rx = time.time()
                    continue
                now = time.time()
                if msg is None:
                    if not silent and now - last_rx > self.SILENT_S and t_first is not None:
                        silent = True
                        self.report(f"link silent for {now - last_rx:.1f} s")
                    continue
                if silent:
                    self.report(f"link back after {now - last_rx:.1f} s of silence")
                    silent = False
                last_rx = now
                if t_first is None:
                    t_first = now
                    if duration is not None:
                        deadline = t_first + duration
                self._take(msg, writers)
        except KeyboardInterrupt:
            self.stop_reason = "SIGINT"
        except OSError as e:  # a write failed: full disk, quota, file size limit
            self.error = f"write failed: {e.strerror or e}"
        finally:
            for s, h in old.items():
                signal.signal(s, h)
            if bus is not None:
                try:
                    bus.shutdown()
                except Exception:
                    pass
            self._close(csv, writers)
        if self.error:
            raise RunFailed(self.error + "; files kept up to the last complete record")
        return self.frames

    def _close(self, csv: CsvChunks, writers):
        try:
            self.decoder.finish()
            csv.close()
        except OSError as e:
            self.error = self.error or f"write failed: {e.strerror or e}"
            csv.buf = []
            try:
                csv.f.close()
            except OSError:
                pass
        for w in writers:
            try:
                w.stop()
            except Exception as e:
                self.error = self.error or f"write failed: {e}"
        for f in self.formats + ["csv"]:
            if f in TEXT_FORMATS:
                p = self.prefix.with_suffix("." + f)
                if p.exists():
                    truncate_to_last_line(p)
        if "blf" in self.formats:
            repair_blf(self.prefix.with_suffix(".blf"))  # a stop() that failed (full disk) leaves a cut container
        try:
            self.arrays = rows_to_arrays(read_rows(self.prefix.with_suffix(".csv")), self.decoder.n, self.decoder.gaps)
            write_capture(
                self.prefix.with_suffix(".npz"),
                self.arrays,
                {"source": self.source, "capture": "rigtools logger", "channel": f"{self.interface}:{self.channel}"},
            )
        except OSError as e:
            why = f"write failed: {e.strerror or e} (the CSV is complete: --repair rebuilds the NPZ)"
            self.error = self.error or why


def channel_source(interface: str, channel: str) -> str:
    """What is on the other end of a channel, as far as the channel tells: a pseudo-terminal is the emulator's
    primary (`python -m host_emulator serve`, which runs the hil model: no rig offers a pty), a USB serial
    device (ttyACM, ttyUSB, cu.usbmodem, COMn) is the rig's primary; anything else is unknown."""
    if interface != "slcan":
        return "unknown"
    dev = channel.split("@", 1)[0]
    try:
        real = os.path.realpath(dev)
    except (OSError, ValueError):
        return "unknown"
    if real.startswith("/dev/pts/") or real.startswith("/dev/ttys"):
        return "emulator:hil"
    name = os.path.basename(real)
    if name.startswith(("ttyACM", "ttyUSB", "cu.usbmodem", "tty.usbmodem")) or name.upper().startswith("COM"):
        return "rig"
    return "unknown"


def check_out(prefix: Path, formats: Sequence[str]) -> str | None:
    """Why the output prefix cannot be written, or None (creates its directory and probes every file it will
    write: a read-only place or a name too long fails here, before the port is opened)."""
    from host_emulator.outpaths import check_out_dir, check_out_file, show

    if prefix.name in ("", ".", ".."):
        return f"--out {show(prefix)}: needs a file name prefix, e.g. out/run1"
    problem = check_out_dir(prefix.parent, f"--out {show(prefix)}: directory")
    if problem:
        return problem
    for f in list(dict.fromkeys(list(formats) + ["csv", "npz", "npz.tmp"])):
        problem = check_out_file(prefix.with_suffix("." + f), "--out")
        if problem:
            return problem
    return None


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except Exception as e:  # noqa: BLE001 - the last guard: one line, never a traceback (MC_DEBUG=1 shows it)
        from host_emulator.cli import unexpected

        return unexpected(e, "logger")


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.rigtools.logger",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run1                 # until Ctrl-C\n"
        "  python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run2 --duration 30 --formats asc\n"
        '  python -m metacell_tools.rigtools.logger -c /dev/pts/3@115200 -o out/run3 --do "2:perturb 8 --torque 0.02 '
        '--duration 0.1"\n'
        "exit codes: 0 ok (also after Ctrl-C, SIGTERM, SIGHUP), 2 bad input, "
        "3 run failed (port, no frames, write error).",
    )
    ap.add_argument("-i", "--interface", default="slcan", help="python-can interface (default slcan)")
    ap.add_argument("-c", "--channel", default=None, help="e.g. /dev/ttyACM0@115200 or <pty>@115200 (required)")
    ap.add_argument("-o", "--out", default=None, help="output prefix, e.g. out/run1 (required)")
    ap.add_argument(
        "--repair",
        metavar="PREFIX",
        default=None,
        help="after a crash, kill or full disk: cut the logs after their last complete record (BLF: object) and "
        "rebuild PREFIX.npz from PREFIX.csv; no port is opened",
    )
    ap.add_argument(
        "--formats", default="asc", help="python-can log formats, comma separated (asc,blf,csv,log,trc,...)"
    )
    ap.add_argument("--bitrate", type=int, default=None, help="CAN bit rate sent as Sn (ignored by the primary)")
    ap.add_argument(
        "--duration", type=float, default=None, help="seconds to log from the first frame (default: until Ctrl-C)"
    )
    ap.add_argument("--give-up", type=float, default=None, help="stop retrying a lost connection after this many s")
    ap.add_argument("--wait-open", type=float, default=0.0, help="keep trying to open the port this many s at start")
    ap.add_argument("--first-frame", type=float, default=30.0, help="fail if no frame arrives in this many s")
    ap.add_argument(
        "--source",
        default=None,
        metavar="LABEL",
        help="what sends the frames, written into the NPZ: rig, emulator:hil, rehearsal:hil or unknown (default: "
        "from the channel: a pty is the emulator's serve, a USB serial device the rig, else unknown; with --repair: "
        "the label of the rebuilt NPZ, default unknown)",
    )
    ap.add_argument(
        "--do",
        action="append",
        default=[],
        metavar="T:COMMAND",
        help="run a command-tool command T s after the first frame through the same port, "
        'e.g. --do "2:perturb 8 --torque 0.02 --duration 0.1"',
    )
    args = ap.parse_args(argv)

    def bad(text):
        print(f"logger: {text}", file=sys.stderr)
        return 2

    if args.source is not None and not (
        args.source in ("rig", "unknown") or args.source.split(":")[0] in ("emulator", "rehearsal")
    ):
        return bad(f"--source {args.source!r}: expected rig, emulator:<model>, rehearsal:<model> or unknown")
    if args.repair is not None:
        try:
            arr = repair(Path(args.repair), source=args.source)
        except RunFailed as e:
            return bad(str(e))
        except OSError as e:
            print(f"logger: --repair {args.repair}: write failed: {e.strerror or e}", file=sys.stderr)
            return 3
        print(
            f"repaired {args.repair}: {int(np.sum(~np.isnan(arr['alpha_counts'])))} samples in "
            f"{len(arr['cycle'])} cycles, {len(arr['gaps'])} gaps; wrote {args.repair}.npz"
        )
        return 0
    if not args.channel or not args.out:
        ap.error("the following arguments are required: -c/--channel, -o/--out (or --repair PREFIX)")

    for name in ("duration", "give_up", "wait_open", "first_frame"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and 0 <= v <= 1e7 and (v > 0 or name == "wait_open")):
            return bad(f"--{name.replace('_', '-')} must be a finite number of seconds in (0, 1e7], got {v}")
    if args.bitrate is not None and not 1 <= args.bitrate <= 1_000_000:
        return bad(f"--bitrate must be in 1..1000000, got {args.bitrate}")
    formats = [f.strip().lstrip(".") for f in args.formats.split(",") if f.strip()]
    known = ("asc", "blf", "csv", "db", "log", "trc", "txt", "mf4")
    if not formats or any(f not in known for f in formats):
        return bad(f"--formats: expected some of {','.join(known)}, got {args.formats!r}")
    problem = check_out(Path(args.out), formats)
    if problem:
        return bad(problem)
    log = RigLogger(
        args.interface,
        args.channel,
        Path(args.out),
        formats,
        args.bitrate,
        give_up_s=args.give_up,
        first_frame_s=args.first_frame,
        wait_open_s=args.wait_open,
        source=args.source,
    )
    from .command import build, parser

    for item in args.do:
        t, sep, text = item.partition(":")
        try:
            tt = float(t)
            if not (sep and math.isfinite(tt) and tt >= 0):
                raise ValueError(f"time {t!r}")
            a = parser().parse_args(["-c", "-"] + text.split())
            build(a)
            log.commands.append((tt, text))
        except (ValueError, SystemExit) as e:
            return bad(f"--do {item!r}: expected T:COMMAND with a valid command ({e})")
    log.commands.sort()
    try:
        n = log.run(args.duration)
    except RunFailed as e:
        print(f"logger: {e}", file=sys.stderr)
        return 3
    arr = log.arrays
    per_cell = np.sum(~np.isnan(arr["alpha_counts"]), axis=0)
    lost = int(arr["gaps"][:, 3].sum()) if len(arr["gaps"]) else 0
    why = f"; stopped by {log.stop_reason}" if log.stop_reason else ""
    print(
        f"{n} frames; samples per cell min {per_cell.min() if len(per_cell) else 0} max "
        f"{per_cell.max() if len(per_cell) else 0}; {len(arr['gaps'])} gaps ({lost} samples lost); "
        f"{log.reconnects} reconnects; {log.corrupt} corrupt lines; "
        + (f"{len(log.others)} other program(s) read the port too; " if log.others else "")
        + f"wrote {args.out}.npz/.csv and "
        f"{','.join(formats)}{why}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
