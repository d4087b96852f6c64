"""The logger's receive loop (RigLogger): python-can writers, decoding, the chunked CSV, reconnects, scheduled
commands through the same port, and the end of a run in order (files complete on a signal or a full disk)."""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import can

from protocol.capture import read_rows, rows_to_arrays
from protocol.wire import N_CELLS

from ..command import RigClient, build, parser
from ..portlock import device_of, holders
from ..slcanbus import open_bus
from .files import (
    TEXT_FORMATS,
    CsvChunks,
    RunFailed,
    SampleDecoder,
    flush_writer,
    repair_blf,
    truncate_to_last_line,
    write_capture,
)


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
        n_cells: int = N_CELLS,
        topology: dict | None = None,
    ) -> None:
        self.interface, self.channel, self.bitrate = interface, channel, bitrate
        self.source = source or channel_source(interface, channel)  # written into the NPZ: rig, emulator or unknown
        self.prefix = Path(prefix)
        self.formats = [f.strip().lstrip(".") for f in formats if f.strip()]
        self.reconnect_s, self.give_up_s = reconnect_s, give_up_s
        self.first_frame_s, self.wait_open_s = first_frame_s, wait_open_s
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self.csv: CsvChunks | None = None
        self.decoder = SampleDecoder(n_cells, report=self.report, hold=True)
        self.topology = topology  # the rig config's, when not the rig as built: written into the NPZ
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
            self.arrays = rows_to_arrays(
                read_rows(self.prefix.with_suffix(".csv"), self.decoder.n), self.decoder.n, self.decoder.gaps
            )
            write_capture(
                self.prefix.with_suffix(".npz"),
                self.arrays,
                {
                    "source": self.source,
                    "capture": "rigtools logger",
                    "channel": f"{self.interface}:{self.channel}",
                    **({"topology": self.topology} if self.topology is not None else {}),
                },
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
