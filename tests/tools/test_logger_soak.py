"""Soak: the rig logger on `serve`'s pty through reader stalls, a server stall, a server kill and restart, and SIGTERM.

Afterwards ASC, CSV and NPZ hold the same samples, time never runs backwards, the gaps are
reported. Stalls are a few seconds here (the unwrap for any stall length is proven in
test_logger_robust.py); run by hand with longer ones (see docs/datapath.md)."""

import os
import re
import signal
import subprocess
import sys
import time

import numpy as np

from metacell_tools.rigtools import proto

ROOT = proto.ROOT
SAMPLE = proto.FRAMES["CELL_SAMPLE"]["base"]
LOGGER_STALL_S = float(os.environ.get("MC_SOAK_STALL_S", "3"))


def start_server(link):
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "host_emulator",
            "serve",
            "exp5_rest",
            "--slcan",
            "--duration",
            "1200",  # stopped by the test; long enough for a loaded machine
            "--link",
            str(link),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = p.stdout.readline()
    assert re.match(r"slcan pty: (\S+)", first), (first, p.stderr.read() if p.poll() is not None else "")
    return p


def stop(p, sig=signal.SIGTERM):
    if p.poll() is None:
        p.send_signal(sig)
        try:
            p.wait(60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(60)


def wait_csv(out, pred, what, timeout=300.0):
    """Poll the logger's CSV until pred(text) holds (rows reach it within 1.5 s of their frame); the timeout is only
    for a badly loaded machine, with a message saying what did not come."""
    csv = out.with_suffix(".csv")
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if csv.exists() and pred(csv.read_text()):
            return
        time.sleep(0.2)
    raise AssertionError(f"no {what} in {csv} after {timeout:.0f} s")


def test_logger_soak_stalls_kill_restart(tmp_path):
    link = tmp_path / "rig"
    out = tmp_path / "soak"
    srv = start_server(link)
    log = None
    try:
        log = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "metacell_tools.rigtools.logger",
                "-c",
                f"{link}@115200",
                "-o",
                str(out),
                "--formats",
                "asc,blf",
                "--first-frame",
                "30",
            ],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        wait_csv(out, lambda text: len(text) >= 10_000, "10 kB of CSV rows")
        time.sleep(1.0)
        log.send_signal(signal.SIGSTOP)  # the logger stalls; the server keeps producing
        time.sleep(LOGGER_STALL_S)
        log.send_signal(signal.SIGCONT)
        time.sleep(2.0)
        srv.send_signal(signal.SIGSTOP)  # the server stalls: the link goes silent
        time.sleep(3.0)  # well over the logger's 1 s silence threshold, even if the logger itself is slowed
        srv.send_signal(signal.SIGCONT)
        time.sleep(1.5)
        srv.kill()  # the server dies and comes back on the same link
        srv.wait(60)
        time.sleep(0.5)
        srv = start_server(link)
        # event-driven: the logger reconnects (every second) and logs a new segment; on a loaded machine that may
        # take long, so wait for 100 cycles of segment 1 rather than a fixed time
        wait_csv(out, lambda text: text.count("\n1,") >= 16 * 100, "100 cycles of segment 1 after the reconnect")
        log.send_signal(signal.SIGTERM)
        o, e = log.communicate(timeout=600)
    finally:
        if log is not None and log.poll() is None:
            log.kill()
        stop(srv)
    if os.environ.get("MC_SOAK_VERBOSE"):
        print(o, e)
    assert log.returncode == 0, e
    assert "stopped by SIGTERM" in o, o
    assert "Traceback" not in e, e
    assert "segment 1: reconnected" in e and "link silent" in e, e
    assert re.search(r"gap: cell \d+ lost \d+ sample", e), e
    # the same samples in ASC, CSV and NPZ
    asc = out.with_suffix(".asc").read_text()
    n_asc = sum(
        1 for x in re.findall(r"^\s*\d+\.\d+\s+1\s+([0-9A-F]{3})\s+Rx", asc, re.M) if SAMPLE < int(x, 16) <= SAMPLE + 16
    )
    lines = out.with_suffix(".csv").read_text().splitlines()
    rows = np.loadtxt(out.with_suffix(".csv"), delimiter=",", skiprows=1, ndmin=2)
    d = np.load(out.with_suffix(".npz"))
    n_npz = int(np.sum(~np.isnan(d["alpha_counts"])))
    assert n_asc == len(lines) - 1 == n_npz, (n_asc, len(lines) - 1, n_npz)
    assert n_asc > 16 * 500
    # time never runs backwards, within a segment or across the reconnect
    assert np.all(np.diff(rows[:, 3]) >= 0)
    assert set(rows[:, 0]) == {0, 1}
    for j in range(1, 17):
        for seg in (0, 1):
            k = rows[(rows[:, 2] == j) & (rows[:, 0] == seg), 1]
            assert np.all(np.diff(k) > 0)  # no cycle repeats: nothing overwritten
    t = d["sample_time"]
    tt = np.nanmax(t, axis=1)
    assert np.all(np.diff(tt) >= 0)
    import can

    n_blf = sum(1 for m in can.BLFReader(str(out.with_suffix(".blf"))) if SAMPLE < m.arbitration_id <= SAMPLE + 16)
    assert n_blf == n_asc
