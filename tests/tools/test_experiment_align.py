"""Captures that include the push: `serve --wait-client` starts the scene when python-can's logger opens the channel,
and `compare` aligns the capture with the emulator's run of the scene on the push (align.py)."""

import re
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest

from metacell_tools.experiment import align
from metacell_tools.experiment.compare import compare
from metacell_tools.rigtools import proto
from tests.conftest import ctrl_c_default

ROOT = proto.ROOT
WAIT_S = 300.0  # upper bound of every wait (each ends when its condition holds): a loaded machine only


def _samples_of_cell_1(path) -> int:
    text = path.read_text() if path.exists() else ""
    return len(re.findall(r"^\s*\d+\.\d+\s+1\s+101\s+Rx", text, re.M))


def test_a_capture_from_serve_wait_client_aligns_with_the_hil_run_on_the_push(tmp_path):
    srv = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "serve", "default", "--slcan", "--wait-client", "--duration", "3600"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    cap = tmp_path / "cap.asc"
    try:
        m = re.match(r"slcan pty: (\S+)", srv.stdout.readline())
        assert m, srv.stderr.read() if srv.poll() is not None else "no pty line"
        banner = srv.stdout.readline()
        assert banner.startswith("scene default: model hil, I2C 400000 Hz, 16 cells (the scene file says: "), banner
        assert "waiting for a client" in srv.stdout.readline()
        time.sleep(1.0)  # the scene must not run while nobody listens: the capture below still holds its push
        logger = subprocess.Popen(
            [sys.executable, "-m", "can.logger", "-i", "slcan", "-c", f"{m.group(1)}@115200", "-f", str(cap)],
            cwd=tmp_path,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            preexec_fn=ctrl_c_default,
        )
        end = time.monotonic() + WAIT_S
        while _samples_of_cell_1(cap) < 150 and time.monotonic() < end and logger.poll() is None:  # 1.35 s
            time.sleep(0.3)
        logger.send_signal(signal.SIGINT)
        try:
            logger.wait(60)
        except subprocess.TimeoutExpired:
            logger.kill()
    finally:
        srv.send_signal(signal.SIGTERM)
        out, _ = srv.communicate(timeout=120)
    assert "client opened the CAN channel (session 1): scene started" in out, out
    assert _samples_of_cell_1(cap) >= 150
    emu = tmp_path / "emu"
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "run", "default", "--set", "t_end_s=1.5", "--out", str(emu)]
        + ["--quiet", "--no-plots"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    text, png = compare(cap, emu, tmp_path / "c.png")
    m = re.search(r"aligned on the push \(alpha_8 moved 2 counts\): A at ([\d.]+) s, B at ([\d.]+) s", text)
    assert m, text
    a_push, b_push = float(m.group(1)), float(m.group(2))
    # the capture began with the scene (its clock: from its first sample, a poll cycle or two after t = 0), so the
    # push is where the scene puts it: 0.1 s plus the time the torque takes to move the cell 2 counts
    assert 0.1 < a_push < 0.2 and abs(a_push - b_push) < 0.03, text
    m = re.search(r"after the push \(0\.\.([\d.]+) s\): alpha differs by ([\d.]+) rad rms", text)
    assert m and float(m.group(1)) > 1.0 and float(m.group(2)) < 0.05, text
    assert (tmp_path / "c_time.png").stat().st_size > 10000 and png.exists()


def _ds(t, alpha):
    """What make_track reads of a dataset: time, alpha and beta by name, each with .values."""
    alpha = np.asarray(alpha, float)
    return {k: SimpleNamespace(values=v) for k, v in (("time", t), ("alpha", alpha), ("beta", np.zeros_like(alpha)))}


def test_alignment_on_the_push_and_a_capture_that_missed_it():
    step = align.MOVE_RAD
    t = np.arange(0, 2, 0.01)

    def run(push_at):  # cell 2 ramps from the push on, cell 1 follows 0.2 s later
        x = np.zeros((t.size, 2))
        x[:, 1] = np.clip(t - push_at, 0, None) * 50 * step
        x[:, 0] = np.clip(t - push_at - 0.2, 0, None) * 20 * step
        return x

    a = align.make_track(_ds(t, run(0.5)), (2, "alpha"))
    b = align.make_track(_ds(t, run(0.1)), (2, "alpha"))
    # 2 counts 0.02 s after the push (the first sample there or, rounding, the next)
    assert a.push_s == pytest.approx(0.52, abs=0.011) and a.pushed == "alpha_2"
    assert b.push_s == pytest.approx(a.push_s - 0.4, abs=1e-9)
    tau, xa, xb = align.aligned(a, b)
    assert tau[0] == pytest.approx(0) and tau[-1] == pytest.approx(1.99 - a.push_s)
    np.testing.assert_allclose(xa, xb, atol=1e-9)  # the same motion, 0.4 s apart on the two clocks
    lines = align.lines(a, b)
    assert f"A at {a.push_s:.4f} s, B at {b.push_s:.4f} s" in lines[0] and "alpha differs by 0.000 rad rms" in lines[1]
    # without a scene: the first cell to move
    assert align.make_track(_ds(t, run(0.5)), None).pushed == "alpha_2"
    # a capture that began after the push: the lattice moves steadily from its first sample, never 2 counts away
    late = align.make_track(_ds(t, np.full((t.size, 2), 0.3)), (2, "alpha"))
    assert late.push_s is None
    (line,) = align.lines(late, b)
    assert "no push in the data (A: alpha_2 never moved 2 counts)" in line and "--wait-client" in line
    assert align.plot(late, b, None, ("a", "b"), "x") is None
