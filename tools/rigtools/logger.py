"""Rig logger on python-can: python-can log files, decoded alpha_j(t)/beta_j(t) arrays (NPZ, CSV), gap reports, reconnects.

    python -m tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run1 --duration 60
    python -m tools.rigtools.logger -c /dev/pts/3@115200 -o out/emu --formats asc,blf

Writes <out>.<fmt> for every python-can format asked for (asc blf csv db log trc txt),
<out>.npz (arrays, see docs/datapath.md) and <out>.csv (one row per cell sample).
Every gap in a cell's sequence counter is reported on stderr as it happens and kept in
the NPZ; a lost connection is reported, retried every second, and logged as a new segment.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from . import proto

RAD_PER_COUNT = 2 * math.pi / 400
T128_S = 128e-6


class SampleDecoder:
    """CELL_SAMPLE frames -> per-cycle rows; gaps from the per-cell sequence counters.

    All cells' counters advance once per poll cycle, so an 8-bit seq names the cycle
    modulo 256; it is unwrapped against the newest cycle seen (frames arrive in order,
    within +-128 cycles of each other). A reconnect starts a new segment."""

    def __init__(self, n_cells: int = proto.N_CELLS, report=None):
        self.n = n_cells
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.db = proto.database()
        self.base = proto.FRAMES["CELL_SAMPLE"]["base"]
        self.rows = []          # (segment, cycle, cell, t_s, host, alpha, beta, flags)
        self.gaps = []          # (segment, cell, first missing cycle, missing count)
        self.status = {}        # (frame kind, cell) -> last decoded dict
        self.events = []        # (host time, text)
        self.segment = 0
        self._reset()

    def _reset(self):
        self.k_last = None
        self.prev = [None] * self.n
        self.t_raw = None
        self.t_s = 0.0

    def new_segment(self, host: float, why: str):
        self.events.append((host, why))
        self.report(f"segment {self.segment + 1}: {why}")
        self.segment += 1
        self._reset()

    def feed(self, msg) -> None:
        kind, j = proto.frame_kind(msg.arbitration_id)
        if kind == "UNKNOWN" or msg.is_extended_id or msg.is_remote_frame:
            return
        if kind == "CELL_SAMPLE":
            d = self.db.decode_message(msg.arbitration_id, bytes(msg.data))
            self.sample(j, d["seq"], d["alpha"], d["beta"], round(d["t128"] / T128_S), d["flags"], msg.timestamp)
        elif kind in ("CELL_STATUS", "CELL_LINK", "PRIMARY_STATUS", "PRIMARY_REJECT", "CMD_RESULT"):
            try:
                self.status[(kind, j)] = self.db.decode_message(msg.arbitration_id, bytes(msg.data))
            except Exception as e:   # wrong length etc.: keep going, say so
                self.report(f"undecodable {kind} frame 0x{msg.arbitration_id:03X}: {e}")

    def sample(self, j, seq, alpha, beta, t128, flags, host):
        if self.k_last is None:
            k = seq
            self.k_last = k
        else:
            k = self.k_last + ((seq - self.k_last + 128) % 256) - 128
            self.k_last = max(self.k_last, k)
        if self.t_raw is not None:
            self.t_s += (((t128 - self.t_raw + 32768) % 65536) - 32768) * T128_S
        self.t_raw = t128
        prev = self.prev[j - 1]
        if prev is not None and k > prev + 1:
            self.gaps.append((self.segment, j, prev + 1, k - prev - 1))
            self.report(f"gap: cell {j} lost {k - prev - 1} sample(s) after cycle {prev} (segment {self.segment})")
        elif prev is not None and k <= prev:
            self.report(f"cell {j}: cycle {k} after {prev} (duplicate or reordered frame)")
        self.prev[j - 1] = k
        self.rows.append((self.segment, k, j, self.t_s, host, alpha, beta, flags))

    def arrays(self) -> dict:
        """Cycle x cell arrays (NaN / -1 where a cell has no sample)."""
        if not self.rows:
            keys = np.zeros((0, 2), dtype=np.int64)
        else:
            keys = np.unique(np.array([(r[0], r[1]) for r in self.rows], dtype=np.int64), axis=0)
        index = {(int(s), int(k)): i for i, (s, k) in enumerate(keys)}
        m = len(keys)
        shape = (m, self.n)
        a = np.full(shape, np.nan)
        b = np.full(shape, np.nan)
        t = np.full(shape, np.nan)
        h = np.full(shape, np.nan)
        fl = np.full(shape, -1, dtype=np.int16)
        for seg, k, j, ts, host, al, be, f in self.rows:
            i = index[(seg, k)]
            a[i, j - 1], b[i, j - 1], t[i, j - 1], h[i, j - 1], fl[i, j - 1] = al, be, ts, host, f
        return {"segment": keys[:, 0], "cycle": keys[:, 1], "cells": np.arange(1, self.n + 1),
                "t_s": t, "host_time": h, "alpha_counts": a, "beta_counts": b,
                "alpha_rad": a * RAD_PER_COUNT, "beta_rad": b * RAD_PER_COUNT, "flags": fl,
                "gaps": np.array(self.gaps, dtype=np.int64).reshape(-1, 4)}

    def save(self, prefix: Path) -> list[Path]:
        prefix = Path(prefix)
        prefix.parent.mkdir(parents=True, exist_ok=True)
        arr = self.arrays()
        npz = prefix.with_suffix(".npz")
        np.savez_compressed(npz, **arr)
        csv = prefix.with_suffix(".csv")
        with open(csv, "w") as f:
            f.write("segment,cycle,cell,t_s,host_time,alpha_counts,beta_counts,flags\n")
            for seg, k, j, ts, host, al, be, fl in self.rows:
                f.write(f"{seg},{k},{j},{ts:.6f},{host:.6f},{al},{be},{fl}\n")
        return [npz, csv]


class RigLogger:
    """Receive loop with python-can writers, decoding and reconnect."""

    def __init__(self, interface: str, channel: str, prefix: Path, formats=("asc",), bitrate=None,
                 reconnect_s: float = 1.0, give_up_s: float | None = None, report=None, open_bus=None):
        self.interface, self.channel, self.bitrate = interface, channel, bitrate
        self.prefix = Path(prefix)
        self.formats = [f.strip().lstrip(".") for f in formats if f.strip()]
        self.reconnect_s, self.give_up_s = reconnect_s, give_up_s
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.decoder = SampleDecoder(report=self.report)
        self.open_bus = open_bus or self._open
        self.frames = 0
        self.reconnects = 0
        self.corrupt = 0
        self.commands = []       # (seconds after start, command-tool arguments)
        self.command_log = []

    def _open(self):
        import can

        kw = {"interface": self.interface, "channel": self.channel}
        if self.bitrate:
            kw["bitrate"] = self.bitrate
        return can.Bus(**kw)

    def _connect(self, deadline):
        first = time.time()
        while True:
            try:
                return self.open_bus()
            except Exception as e:   # python-can and pyserial raise several types
                if self.give_up_s is not None and time.time() - first > self.give_up_s:
                    raise
                if deadline is not None and time.time() >= deadline:
                    return None
                self.report(f"cannot open {self.channel}: {e}; retrying in {self.reconnect_s} s")
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

    def run(self, duration: float | None = None) -> int:
        import can

        self.prefix.parent.mkdir(parents=True, exist_ok=True)
        writers = [can.Logger(str(self.prefix.with_suffix("." + f))) for f in self.formats]
        deadline = None if duration is None else time.time() + duration
        bus = self._connect(deadline)
        t_start = time.time()
        try:
            while bus is not None and (deadline is None or time.time() < deadline):
                self._due_commands(bus, writers, t_start)
                try:
                    msg = bus.recv(timeout=0.2)
                except ValueError as e:
                    # python-can could not parse a line (e.g. bytes lost on the port): the line is gone, go on
                    self.corrupt += 1
                    self.report(f"corrupt SLCAN line skipped: {e}")
                    continue
                except Exception as e:
                    lost = time.time()
                    self.report(f"connection lost: {e}")
                    try:
                        bus.shutdown()
                    except Exception:
                        pass
                    bus = self._connect(deadline)
                    if bus is None:
                        break
                    self.reconnects += 1
                    self.decoder.new_segment(time.time(), f"reconnected after {time.time() - lost:.1f} s "
                                                          "(samples in between are lost)")
                    continue
                if msg is not None:
                    self._take(msg, writers)
        except KeyboardInterrupt:
            pass
        finally:
            if bus is not None:
                bus.shutdown()
            for w in writers:
                w.stop()
        self.decoder.save(self.prefix)
        return self.frames


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.rigtools.logger", description=__doc__.split("\n\n")[0])
    ap.add_argument("-i", "--interface", default="slcan", help="python-can interface (default slcan)")
    ap.add_argument("-c", "--channel", required=True, help="e.g. /dev/ttyACM0@115200 or <pty>@115200")
    ap.add_argument("-o", "--out", required=True, help="output prefix, e.g. out/run1")
    ap.add_argument("--formats", default="asc", help="python-can log formats, comma separated (asc,blf,csv,log,trc,...)")
    ap.add_argument("--bitrate", type=int, default=None, help="CAN bit rate sent as Sn (ignored by the primary)")
    ap.add_argument("--duration", type=float, default=None, help="seconds to log (default: until Ctrl-C)")
    ap.add_argument("--give-up", type=float, default=None, help="stop retrying a lost connection after this many s")
    ap.add_argument("--do", action="append", default=[], metavar="T:COMMAND",
                    help='run a command-tool command T s after start through the same port, '
                         'e.g. --do "2:perturb 8 --torque 0.02 --duration 0.1"')
    args = ap.parse_args(argv)
    log = RigLogger(args.interface, args.channel, Path(args.out), args.formats.split(","), args.bitrate,
                    give_up_s=args.give_up)
    from .command import build, parser
    for item in args.do:
        t, sep, text = item.partition(":")
        try:
            build(parser().parse_args(["-c", "-"] + text.split()))
            log.commands.append((float(t), text))
        except (ValueError, SystemExit):
            print(f"error: --do {item!r}: expected T:COMMAND with a valid command", file=sys.stderr)
            return 2
    log.commands.sort()
    n = log.run(args.duration)
    arr = log.decoder.arrays()
    per_cell = np.sum(~np.isnan(arr["alpha_counts"]), axis=0)
    lost = int(arr["gaps"][:, 3].sum()) if len(arr["gaps"]) else 0
    print(f"{n} frames; samples per cell min {per_cell.min() if len(per_cell) else 0} max "
          f"{per_cell.max() if len(per_cell) else 0}; {len(arr['gaps'])} gaps ({lost} samples lost); "
          f"{log.reconnects} reconnects; {log.corrupt} corrupt lines; wrote {args.out}.npz/.csv and {args.formats}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
