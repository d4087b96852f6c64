"""No client can take the image tier's `serve` down: a raw client flooding the pty with command frames at 10 kHz for
10 s meets back-pressure (its writes wait while the emulated USB host is full), the server keeps serving, and every
command it sent gets its CMD_RESULT (issue 32, item 2: it used to stop with "the USB host's buffer is full")."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
from collections import Counter

import pytest

from metacell_tools.rigtools import proto

pytestmark = pytest.mark.slow
ROOT = proto.ROOT
RATE_HZ = 10_000  # command frames per second of the client's own (wall) clock, at most
FLOOD_S = 10.0
BATCH = 50  # frames per write: RATE_HZ in batches every BATCH / RATE_HZ s
WAIT_S = 600.0  # an upper bound only: the wait for the answers ends when the last one comes


def slcan_line(ident: int, data: bytes) -> bytes:
    return f"t{ident:03X}{len(data)}{data.hex().upper()}\r".encode()


class Reader(threading.Thread):
    """Reads the client's end of the pty as fast as it comes: CMD_RESULT frames per cell, CELL_SAMPLE frames."""

    def __init__(self, fd: int) -> None:
        super().__init__(daemon=True)
        self.fd, self.stop = fd, threading.Event()
        self.results: Counter[int] = Counter()
        self.samples = 0
        self.buf = b""

    def run(self) -> None:
        pattern = re.compile(rb"t([0-9A-F]{3})([0-8])")
        while not self.stop.is_set():
            if not select.select([self.fd], [], [], 0.1)[0]:
                continue
            try:
                self.buf += os.read(self.fd, 1 << 16)
            except OSError:
                return
            *lines, self.buf = self.buf.split(b"\r")
            for line in lines:
                m = pattern.search(line)  # the SLCAN acks (a bare \r) and BELs come before a frame on one line
                if not m:
                    continue
                kind, j = proto.frame_kind(int(m.group(1), 16))
                if kind == "CMD_RESULT":
                    self.results[j] += 1
                elif kind == "CELL_SAMPLE":
                    self.samples += 1


def test_a_10_khz_command_flood_is_served_and_every_command_answered(images):
    p = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "serve", "exp5_rest", "--slcan", "--set", "model=image"]
        + ["--duration", "3600"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first = p.stdout.readline()  # after the boards booted and the cells were configured
        m = re.match(r"slcan pty: (\S+)", first)
        assert m, (first, p.stderr.read() if p.poll() is not None else "")
        fd = os.open(m.group(1), os.O_RDWR | os.O_NOCTTY)  # blocking writes: they wait while serve holds back
        reader = Reader(fd)
        reader.start()
        sent: Counter[int] = Counter()
        os.write(fd, b"O\r")
        k = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < FLOOD_S:
            batch = b""
            for _ in range(BATCH):
                j = k % 16 + 1
                batch += slcan_line(proto.cmd_frame_id(j), proto.cmd_data("CLEAR_FAULTS", k & 0xFF))
                sent[j] += 1
                k += 1
            view = memoryview(batch)
            while view:
                view = view[os.write(fd, view) :]
            ahead = t0 + k / RATE_HZ - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
            assert p.poll() is None, p.stderr.read()
        # every command the client sent reaches the primary (nothing is refused or lost on the way) and is answered
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and reader.results != sent and p.poll() is None:
            time.sleep(0.5)
        assert p.poll() is None, p.stderr.read()
        assert reader.results == sent, (sum(sent.values()), sum(reader.results.values()))
        before = reader.samples
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and reader.samples < before + 160:  # and it keeps serving
            time.sleep(0.2)
        assert reader.samples >= before + 160
        os.write(fd, b"C\r")
        reader.stop.set()
        reader.join()
        os.close(fd)
    finally:
        p.send_signal(signal.SIGTERM)
        try:
            out, err = p.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            p.kill()
            raise
    assert p.returncode == 0, (out, err)
    held = re.search(r"at most (\d+) bytes held back", out)
    # the flood outran the primary: serve held bytes back (the test exercised the back-pressure)
    assert held and int(held.group(1)) > 0, out
    print(f"{k} commands sent; {out.strip().splitlines()[-1]}")
