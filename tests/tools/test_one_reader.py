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


def test_the_logger_reports_a_program_that_opens_its_port_later(tmp_path):
    """python -m can.logger takes no lock: opened after the logger, it is seen and reported (and counted)."""
    srv = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "serve", "exp5_rest", "--duration", "600"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    other = log = None
    try:
        pty = re.match(r"slcan pty: (\S+)", srv.stdout.readline()).group(1)
        log = subprocess.Popen(
            [sys.executable, "-m", "metacell_tools.rigtools.logger", "-c", f"{pty}@115200", "-o", str(tmp_path / "l")],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        csv = tmp_path / "l.csv"
        deadline = time.monotonic() + 300  # event-driven: the logger is logging once rows reach its CSV
        while not (csv.exists() and csv.stat().st_size > 1000) and time.monotonic() < deadline:
            assert log.poll() is None, log.communicate()
            time.sleep(0.2)
        other = hold(pty)
        line = ""
        deadline = time.monotonic() + 300
        while "another program opened" not in line and time.monotonic() < deadline:
            line = log.stderr.readline()
            assert line or log.poll() is None, "the logger exited"
        assert f"pid {other.pid}" in line, line
        log.send_signal(signal.SIGTERM)
        out, _ = log.communicate(timeout=300)
    finally:
        for p in (other, log):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
        srv.send_signal(signal.SIGTERM)
        srv.communicate(timeout=120)
    assert log.returncode == 0 and "1 other program(s) read the port too" in out, out
