"""Acceptance: python-can's slcan interface on the pty of `python -m host_emulator serve` gets all 16 cells
(DBC-decodable), and a write changes a cell's behaviour."""

import re
import signal
import subprocess
import sys
import time

import can
import pytest

from metacell_tools.rigtools import proto
from tests.conftest import ctrl_c_default

ROOT = proto.ROOT


@pytest.fixture(scope="module")
def server():
    p = subprocess.Popen(
        # a module's worth of tests on a loaded machine can outlast a minute: run on until SIGTERM at teardown
        [sys.executable, "-m", "host_emulator", "serve", "exp5_rest", "--slcan", "--duration", "3600"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = p.stdout.readline()
    m = re.match(r"slcan pty: (\S+)", first)
    assert m, (first, p.stderr.read() if p.poll() is not None else "")
    yield m.group(1)
    p.send_signal(signal.SIGTERM)
    try:
        p.wait(60)
    except subprocess.TimeoutExpired:
        p.kill()


def collect(bus, seconds):
    out = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        m = bus.recv(timeout=0.1)
        if m is not None:
            out.append(m)
    return out


WAIT_S = 120.0  # every wait for an answer ends when the answer comes; this long only on a badly loaded machine


def until(bus, pred, timeout=WAIT_S):
    """Frames until pred(frames) holds (event-driven: the server is paced to wall time and a loaded machine slows
    it; the generous timeout is only an upper bound)."""
    out = []
    end = time.monotonic() + timeout
    while time.monotonic() < end and not pred(out):
        m = bus.recv(timeout=0.1)
        if m is not None:
            out.append(m)
    return out


RESEND_S = 15.0  # a starved reader loses frames (serve drops output past its backlog): send again, as a tool would


def command(bus, j, reg, seq, **values):
    msg = can.Message(
        arbitration_id=proto.cmd_frame_id(j), data=proto.cmd_data(reg, seq, **values), is_extended_id=False
    )
    end = time.monotonic() + WAIT_S
    resend = 0.0
    while time.monotonic() < end:
        if time.monotonic() >= resend:
            bus.send(msg)
            resend = time.monotonic() + RESEND_S
        m = bus.recv(timeout=0.1)
        if m is not None and proto.frame_kind(m.arbitration_id) == ("CMD_RESULT", j) and m.data[1] == seq:
            return proto.RESULT_NAMES[m.data[2]]
    return f"no CMD_RESULT for {reg} seq {seq} to cell {j} within {WAIT_S:g} s"


def n_samples_all(msgs):
    return sum(1 for m in msgs if proto.frame_kind(m.arbitration_id)[0] == "CELL_SAMPLE")


def n_samples(msgs, j):
    fid = proto.FRAMES["CELL_SAMPLE"]["base"] + j
    return sum(1 for m in msgs if m.arbitration_id == fid)


def alphas(msgs, j):
    db = proto.database()
    return [
        db.decode_message(m.arbitration_id, bytes(m.data), scaling=False)["alpha"]
        for m in msgs
        if proto.frame_kind(m.arbitration_id) == ("CELL_SAMPLE", j)
    ]


def test_python_can_slcan_gets_all_cells_and_commands_act(server):
    db = proto.database()
    with can.Bus(interface="slcan", channel=f"{server}@115200", bitrate=500000) as bus:
        msgs = until(
            bus,
            lambda fr: all(n_samples(fr, j) for j in range(1, 17)) and n_samples_all(fr) > 16 * 10,
        )
        cells = set()
        for m in msgs:
            d = db.decode_message(m.arbitration_id, bytes(m.data))  # every frame decodes with the DBC
            kind, j = proto.frame_kind(m.arbitration_id)
            if kind == "CELL_SAMPLE":
                cells.add(j)
                assert set(d) == {"seq", "alpha", "beta", "t128", "flags"}
        assert cells == set(range(1, 17))
        assert len([m for m in msgs if proto.frame_kind(m.arbitration_id)[0] == "CELL_SAMPLE"]) > 16 * 10

        # a parameter write changes behaviour: with PWM limit 0 a perturbation cannot move the motor
        assert command(bus, 12, "PWM_LIMIT", 1, ticks=0) == "OK"
        assert command(bus, 12, "PERTURB", 2, chain=0, torque=7500, ticks=400) == "OK"  # 30 mN*m, 0.2 s
        held = alphas(until(bus, lambda fr: n_samples(fr, 12) >= 50), 12)  # >= 0.45 s of samples
        assert len(held) >= 50 and max(abs(a) for a in held) <= 2
        assert command(bus, 4, "PERTURB", 3, chain=0, torque=7500, ticks=400) == "OK"
        moved = alphas(until(bus, lambda fr: n_samples(fr, 4) >= 50), 4)
        assert len(moved) >= 50 and max(abs(a) for a in moved) >= 20
        # bad input is answered, not acted on
        assert command(bus, 4, "SIGMA", 4, value=10**7) == "RANGE"


def test_python_can_logger_records_the_emulator(server, tmp_path):
    out = tmp_path / "emu.asc"
    p = subprocess.Popen(
        [sys.executable, "-m", "can.logger", "-i", "slcan", "-c", f"{server}@115200", "-f", str(out)],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        preexec_fn=ctrl_c_default,
    )
    want = {proto.FRAMES["CELL_SAMPLE"]["base"] + j for j in range(1, 17)}

    def ids():
        text = out.read_text() if out.exists() else ""
        return set(int(x, 16) for x in re.findall(r"^\s*\d+\.\d+\s+1\s+([0-9A-F]{3})\s+Rx", text, re.M))

    end = time.monotonic() + WAIT_S  # event-driven: until every cell's samples are in the file (it is flushed often)
    while not want <= ids() and time.monotonic() < end and p.poll() is None:
        time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    try:
        p.wait(60)
    except subprocess.TimeoutExpired:
        p.kill()
    assert want <= ids(), f"cells missing from the ASC after {WAIT_S:g} s: {sorted(want - ids())}"


@pytest.mark.parametrize(
    "args,msg",
    [
        (["nosuchscene"], "unknown scene"),
        (["continuum_single"], "needs model"),
        (["default", "--speed", "0"], "--speed"),
        (["default", "--speed", "nan"], "--speed"),
        (["default", "--duration", "nan"], "--duration"),
        (["default", "--period-us", "-1"], "--period-us"),
        (["default", "--stuck", "17"], "outside 1..16"),
    ],
)
def test_serve_refuses_bad_arguments(args, msg):
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "serve", *args, "--slcan"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2 and msg in r.stderr and "slcan pty" not in r.stdout


def test_a_dead_client_leaves_nothing_stale(server):
    """A client opens the channel, stops reading, dies mid-line without C: the next client gets only fresh
    frames and its first command succeeds."""
    import serial

    dead = serial.Serial(server, 115200, timeout=0.1)
    dead.write(b"O\r")
    time.sleep(2.0)  # frames pile up unread
    dead.write(proto.cmd_frame_id(3).to_bytes(2, "big").hex().encode()[:3])  # half a line
    dead.close()  # dies without C
    time.sleep(0.5)
    with can.Bus(interface="slcan", channel=f"{server}@115200", sleep_after_open=0.5) as bus:
        first = until(bus, lambda fr: n_samples_all(fr) > 100)
        samples = [m for m in first if proto.frame_kind(m.arbitration_id)[0] == "CELL_SAMPLE"]
        assert len(samples) > 100
        db = proto.database()
        t0, t1 = (db.decode_message(m.arbitration_id, bytes(m.data))["t128"] for m in (samples[0], samples[-1]))
        primary_span = (t1 - t0) % 8.388608
        host_span = samples[-1].timestamp - samples[0].timestamp
        # stale frames would span seconds of primary time read in a moment
        assert primary_span < host_span + 0.5, (primary_span, host_span)
        assert command(bus, 5, "ENABLE", 42, on=1) == "OK"
