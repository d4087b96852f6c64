"""One reader per serial port: the tools refuse a port another program holds (one line, exit 3, nothing sent), lock
the ports they hold, and `serve` counts a second program on its pty."""

import os
import re
import signal
import subprocess
import sys
import time

import pytest

from metacell_tools.rigtools import portlock, proto

ROOT = proto.ROOT
HOLD = (
    "import os, sys, time; fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY); print('held', flush=True); "
    "time.sleep(600)"
)


@pytest.fixture
def pty():
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    yield path
    os.close(master)


def hold(path):
    """Another program holding the port open (as python -m can.logger would), started and ready."""
    p = subprocess.Popen([sys.executable, "-c", HOLD, path], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "held"
    return p


def test_holders_finds_another_process_and_claim_refuses(pty):
    assert portlock.holders(pty) == {}
    other = hold(pty)
    try:
        held = portlock.holders(pty)
        assert list(held) == [other.pid] and held[other.pid].startswith(sys.executable)
        with pytest.raises(portlock.PortBusy, match=f"pid {other.pid}"):
            portlock.claim(f"{pty}@115200")
    finally:
        other.kill()
        other.wait()
    assert portlock.holders(pty) == {}


def test_two_claims_in_one_process_exclude_each_other(pty):
    fd = portlock.claim(f"{pty}@115200")
    try:
        with pytest.raises(portlock.PortBusy, match="locked"):
            portlock.claim(pty)
    finally:
        portlock.release(fd)
    portlock.release(portlock.claim(pty))  # free again


def test_not_a_device_is_left_to_python_can(tmp_path):
    assert portlock.claim("socket://127.0.0.1:1") is None
    assert portlock.claim(str(tmp_path / "nope")) is None


@pytest.mark.parametrize(
    "argv",
    [
        ["metacell_tools.rigtools.logger", "-o", "{tmp}/log", "--duration", "5"],
        ["metacell_tools.rigtools.command", "enable", "all", "off"],
    ],
    ids=["logger", "command"],
)
def test_tools_refuse_a_busy_port_with_one_line(argv, pty, tmp_path):
    other = hold(pty)
    try:
        module, *rest = argv
        rest = [a.format(tmp=tmp_path) for a in rest]
        r = subprocess.run(
            [sys.executable, "-m", module, "-c", f"{pty}@115200", *rest],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        other.kill()
        other.wait()
    err = r.stderr.strip()
    assert r.returncode == 3 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "in use by another program" in err and f"pid {other.pid}" in err, err


def test_serve_counts_a_second_client():
    srv = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "serve", "exp5_rest", "--duration", "600"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    clients = []
    try:
        m = re.match(r"slcan pty: (\S+)", srv.stdout.readline())
        assert m
        clients = [hold(m.group(1)), hold(m.group(1))]
        # event-driven: serve says so on stderr within about a second of the second client; generous for load
        line = ""
        deadline = time.monotonic() + 120
        while "programs hold" not in line and time.monotonic() < deadline:
            line = srv.stderr.readline()
            assert line or srv.poll() is None, "serve exited"
        assert "2 programs hold" in line and all(f"pid {c.pid}" in line for c in clients), line
    finally:
        for c in clients:
            c.kill()
            c.wait()
        srv.send_signal(signal.SIGTERM)
        out, _ = srv.communicate(timeout=120)
    assert re.search(r"1 second-client events \(most programs on the pty at once: 2\)", out), out
