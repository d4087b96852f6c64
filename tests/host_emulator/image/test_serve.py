"""Acceptance: python-can talks to the real primary image through `serve --slcan --set model=image`: its slcan
interface gets all 16 cells and a command acts; `python -m can.logger` records frames of every cell."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import can
import pytest

from host_emulator.image import build
from metacell_tools.rigtools import proto
from tests.conftest import ctrl_c_default
from tests.host_emulator.bus.test_serve import WAIT_S, alphas, command, n_samples, n_samples_all, until

pytestmark = pytest.mark.slow
ROOT = proto.ROOT


@pytest.fixture(scope="module")
def server(images):
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "host_emulator",
            "serve",
            "exp5_rest",
            "--slcan",
            "--set",
            "model=image",
            "--duration",
            "3600",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = p.stdout.readline()  # after the boards booted and the cells were configured (seconds of wall time)
    m = re.match(r"slcan pty: (\S+)", first)
    assert m, (first, p.stderr.read() if p.poll() is not None else "")
    banner = p.stdout.readline()  # the model the --set chose, not the one the scene file's description names
    assert banner.startswith("scene exp5_rest: model image, I2C 400000 Hz, 16 cells (the scene file says: "), banner
    yield m.group(1)
    p.send_signal(signal.SIGTERM)
    try:
        out, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        p.kill()
        raise
    assert "served" in out and p.returncode == 0, (out, err)


def test_python_can_talks_to_the_primary_image(server):
    db = proto.database()
    with can.Bus(interface="slcan", channel=f"{server}@115200", bitrate=500000) as bus:
        msgs = until(bus, lambda fr: all(n_samples(fr, j) for j in range(1, 17)) and n_samples_all(fr) > 16 * 5)
        assert all(n_samples(msgs, j) for j in range(1, 17))
        for m in msgs:
            db.decode_message(m.arbitration_id, bytes(m.data))  # every frame the image sent decodes with the DBC
        # a command acts, through the primary image's relay and the cell image's register handler
        assert command(bus, 12, "PWM_LIMIT", 1, ticks=0) == "OK"
        assert command(bus, 12, "PERTURB", 2, chain=0, torque=7500, ticks=400) == "OK"  # 30 mN*m for 0.2 s
        held = alphas(until(bus, lambda fr: n_samples(fr, 12) >= 30), 12)
        assert len(held) >= 30 and max(abs(a) for a in held) <= 2
        assert command(bus, 4, "PERTURB", 3, chain=0, torque=7500, ticks=400) == "OK"
        moved = alphas(until(bus, lambda fr: n_samples(fr, 4) >= 30), 4)
        assert len(moved) >= 30 and max(abs(a) for a in moved) >= 20
        assert command(bus, 4, "SIGMA", 4, value=10**7) == "RANGE"  # refused by the cell image


def test_can_logger_records_every_cell_from_the_primary_image(server, tmp_path):
    out = tmp_path / "rig.asc"
    p = subprocess.Popen(
        [sys.executable, "-m", "can.logger", "-i", "slcan", "-c", f"{server}@115200", "-f", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=ctrl_c_default,  # a suite run in the background would pass SIGINT on ignored
    )

    def cells() -> set[int]:
        if not out.exists():
            return set()
        ids = {int(m.group(1), 16) for m in re.finditer(r"\s([0-9A-F]{3})\s+Rx", out.read_text(errors="replace"))}
        base = proto.FRAMES["CELL_SAMPLE"]["base"]
        return {i - base for i in ids if 1 <= i - base <= 16}

    try:
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and cells() != set(range(1, 17)):
            time.sleep(0.5)
    finally:
        p.send_signal(signal.SIGINT)
        try:
            p.wait(60)
        except subprocess.TimeoutExpired:
            p.kill()
    assert cells() == set(range(1, 17))


def test_serve_refuses_the_hil_bus_options_for_the_image_tier(images):
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "serve", "--slcan", "--set", "model=image", "--absent", "3"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 2 and "[[fault]]" in r.stderr and r.stderr.count("\n") == 1, r.stderr


def test_the_tier_says_in_one_line_when_it_cannot_run(tmp_path):
    """No PlatformIO tree, no ~/.platformio and no images built before: `run --set model=image` says so in one line
    (exit 2). (With images in the build directory the tier runs them: its register table needs no tree.)"""
    env = {"HOME": str(tmp_path), "PATH": "/usr/bin:/bin", "MC_PIO_TREE": "", "MC_BUILD_DIR": str(tmp_path / "build")}
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "run", "default", "--set", "model=image", "--set", "t_end_s=0.1"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "MC_PIO_TREE" in r.stderr, r.stderr
    assert build.how_to_build.__doc__  # the same one-line reasons come from build.how_to_build


def test_commands_sent_at_once_on_opening_are_all_answered(server):
    """A client that opens the port and at once writes the channel open and a command to each cell in one write (as
    a script does) gets every CMD_RESULT: its bytes reach the primary only after the port's new line state (DTR up)
    did, as a laptop's open() returns only then, and the primary takes that state before it reads another byte.
    (Both were wrong: the primary read the first frames in the session before, then closed the channel on the DTR
    it saw late, answering the rest with BEL and streaming nothing.)"""
    from .test_serve_flood import Reader, slcan_line

    fd = os.open(server, os.O_RDWR | os.O_NOCTTY)
    reader = Reader(fd)
    reader.start()
    try:
        sent = b"O\r" + b"".join(
            slcan_line(proto.cmd_frame_id(j), proto.cmd_data("CLEAR_FAULTS", j)) for j in range(1, 17)
        )
        os.write(fd, sent)
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and sum(reader.results.values()) < 16:
            time.sleep(0.2)
        samples = reader.samples
        while time.monotonic() < end and reader.samples < samples + 32:  # and the channel stays open
            time.sleep(0.2)
        os.write(fd, b"C\r")
    finally:
        reader.stop.set()
        reader.join()
        os.close(fd)
    assert reader.results == {j: 1 for j in range(1, 17)}, reader.results
    assert reader.samples >= samples + 32
