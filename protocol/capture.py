"""The capture decoder beside the wire definition: CELL_SAMPLE frames to per-cycle rows, and the row table to cycle x
cell arrays. The rig logger, the experiment runner and he.load (python-can logs, logger CSVs) read captures with it.

A row is (segment, cycle, cell, t_s, host_time, alpha_counts, beta_counts, flags): one cell's sample, its cycle
unwrapped from the 8-bit sequence counter and its time from the primary's 16-bit 128 us clock (SampleDecoder);
`rows_to_arrays` turns a row table into the cycle x cell arrays (NaN / -1 where a cell has no sample), with each
cycle's `partial` flag (partial_cycles) and the gap table (gaps_from_rows, or the decoder's own). The logger's
CSV holds the rows (CSV_HEADER, format_rows, read_rows). See docs/datapath.md.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import definition as D
from . import wire
from .codec import RAD_PER_COUNT

if TYPE_CHECKING:
    import can

T128_S = 128e-6
T_WRAP = 1 << 16  # the frames' time field wraps every 65536 x 128 us = 8.39 s
CSV_HEADER = "segment,cycle,cell,t_s,host_time,alpha_counts,beta_counts,flags\n"


def reset_cause_names(bits: int) -> list[str]:
    """Names of the RESET_CAUSE bits set in a BOOT.reset_cause / PRIMARY_HEALTH.reset_cause byte."""
    return [name for name, b in sorted(D.RESET_CAUSE.items(), key=lambda kv: kv[1]) if bits >> b & 1]


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
        n_cells: int = wire.N_CELLS,
        report: Callable[[str], None] | None = None,
        sink: Callable[[list[tuple]], None] | None = None,
        hold: bool = False,
    ) -> None:
        self.n = n_cells
        self.hold = hold
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.db = wire.database()
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
        kind, j = wire.frame_kind(msg.arbitration_id, max(self.n, wire.N_CELLS))  # 16 cells, or a bigger sheet's
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


def read_rows(csv: Path, n_cells: int = wire.N_CELLS) -> np.ndarray:
    """The row table of a streamed CSV (complete lines only). A row that is not one of the logger's (a column that
    is no number, a segment or cycle that is not a whole number, a cell outside the rig's 1..n_cells) is a
    ValueError naming its line: foreign rows never widen the capture to cells the rig has not."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    if rows.size and rows.shape[1] != 8:
        raise ValueError(f"{rows.shape[1]} columns, the logger writes 8 ({CSV_HEADER.strip()})")
    rows = rows.reshape(-1, 8)
    for col, name, lo, hi in ((2, "cell", 1, n_cells), (0, "segment", 0, None), (1, "cycle", None, None)):
        v = rows[:, col]
        bad = ~np.isfinite(v) | (v != np.round(v))
        if lo is not None:
            bad |= v < lo
        if hi is not None:
            bad |= v > hi
        if bad.any():
            i = int(np.argmax(bad))
            want = (
                f"a whole number in {lo}..{hi}" if hi is not None else "a whole number" + (" >= 0" if lo == 0 else "")
            )
            raise ValueError(f"data row {i + 1}: {name} {v[i]:g}, expected {want} (not a row of this rig's logger)")
    return rows


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
