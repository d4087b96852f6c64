"""Dask at the edges: a Ctrl-C to the terminal's process group (every worker process gets SIGINT too) ends a sweep
with its one clean line and no worker traceback; the scheduler check tells a real Dask scheduler from a service
that is not one (which Dask's own client would take a greeting of for an exabyte frame length)."""

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from host_emulator.workbench.sweep import cluster
from host_emulator.workbench.sweep.errors import SweepError, SweepFailed
from tests.conftest import ctrl_c_default

ROOT = Path(__file__).resolve().parents[3]


def _ctrl_c_session():
    ctrl_c_default()
    os.setsid()  # its own process group, as a terminal's foreground job: the test signals that group


@pytest.mark.slow
def test_ctrl_c_to_the_process_group_prints_no_worker_traceback(tmp_path):
    """The issue's probe (`--workers 2`, SIGINT to the process group): about 30 lines of Dask worker traceback
    before the clean message, 3 of 3 times. The signal goes once the first chunk is recorded (the workers run
    by then; no sleep decides it)."""
    out = tmp_path / "s"
    p = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "sweep", "default", "--grid", "params.sigma=0.04:0.12:400",
         "--set", "t_end_s=2", "--workers", "2", "--chunk", "2", "--no-plots", "--out", str(out)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_session,
    )  # fmt: skip
    pf = out / "points.jsonl"
    try:
        deadline = time.monotonic() + 600  # event-driven: the first finished chunk, however slow the machine
        while not (pf.exists() and pf.stat().st_size) and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert p.poll() is None, "the sweep ended before it could be interrupted"
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=600)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert "Traceback" not in err and "KeyboardInterrupt" not in err and "CancelledError" not in err, err
    assert p.returncode == 3 and err.strip().splitlines()[-1].startswith("sweep: interrupted"), err


@pytest.mark.slow
def test_ctrl_c_to_design_on_dask_prints_no_client_traceback(tmp_path):
    """design --scheduler: a Ctrl-C while the hil ensembles run on the cluster (the scheduler holds the design's
    tasks: no sleep decides it) printed the client's cancelled gather tasks ("Task exception was never retrieved",
    AllExit tracebacks) before its line."""
    from distributed import Client

    from tests.host_emulator.workbench.test_sweep import _start_cluster, _stop

    addr, procs = _start_cluster(tmp_path, n_workers=1)
    p = None
    try:
        p = subprocess.Popen(
            [sys.executable, "-m", "host_emulator", "design", "--target", "lambda=10", "--push", "8", "--quiet",
             "--scheduler", addr, "--out", str(tmp_path / "d")],
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_session,
        )  # fmt: skip
        with Client(addr, timeout="60s") as c:
            deadline = time.monotonic() + 600
            while p.poll() is None and time.monotonic() < deadline:
                if c.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)):
                    break
                time.sleep(0.2)
        assert p.poll() is None, "design ended before it could be interrupted"
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=600)
    finally:
        if p is not None and p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        _stop(procs)
    assert "Traceback" not in err and "never retrieved" not in err, err
    assert p.returncode == 3 and err.strip().splitlines() == ["error: interrupted"], err


def _server(greeting: bytes | None):
    """A TCP service on a free port: greeting sent on accept, then the connection closed."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)

    def serve():
        while True:
            try:
                c, _ = srv.accept()
            except OSError:
                return
            if greeting:
                try:
                    c.sendall(greeting)
                except OSError:
                    pass
            c.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv


@pytest.mark.parametrize(
    "greeting",
    [b"SSH-2.0-OpenSSH_9.6\r\n", b"HTTP/1.1 400 Bad Request\r\n\r\n", b"\x00" * 8, b"\x08" + b"\x00" * 7, None],
    ids=["ssh", "http", "zero-length", "cut-frame", "closes"],
)
def test_a_service_that_is_not_dask_is_bad_input(greeting):
    srv = _server(greeting)
    try:
        with pytest.raises(SweepError, match="not as a Dask scheduler"):
            cluster.check_scheduler(f"tcp://127.0.0.1:{srv.getsockname()[1]}")
    finally:
        srv.close()


def test_a_silent_service_is_bad_input(monkeypatch):
    """A service that waits for the client to speak first (HTTP, a database): no handshake within HANDSHAKE_S."""
    monkeypatch.setattr(cluster, "HANDSHAKE_S", 0.3)
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)  # accepted by the kernel, never answered
    try:
        with pytest.raises(SweepError, match="sent no Dask handshake"):
            cluster.check_scheduler(f"127.0.0.1:{srv.getsockname()[1]}")
    finally:
        srv.close()


@pytest.mark.parametrize("address", ["bogus", "tcp://host", "http://127.0.0.1:8786", "tcp://:8786", "tls://a:1"])
def test_an_address_that_is_not_tcp_host_port_is_bad_input(address):
    with pytest.raises(SweepError, match="expected tcp://HOST:PORT"):
        cluster.check_scheduler(address)


def test_nobody_listening_is_a_failed_run():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(SweepFailed, match="cannot connect"):
        cluster.check_scheduler(f"tcp://127.0.0.1:{port}")


def test_a_real_dask_scheduler_passes():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=None) as lc:
        addr = lc.scheduler_address
        assert cluster.check_scheduler(addr) == addr
        assert cluster.check_scheduler(addr.removeprefix("tcp://")) == addr
        with Client(addr, timeout="30s") as c:  # the probe left the scheduler serving
            assert c.scheduler_info()["address"] == addr
