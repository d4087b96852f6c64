"""The Dask side: a local cluster or an existing scheduler, the points cut into chunks, each chunk's results
appended to points.jsonl as it finishes (a chunk that fails has its points recorded as failed)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ...progress import bar as progress_bar
from .errors import SweepError, SweepFailed
from .points import evaluate_points
from .store import _jsonable

if TYPE_CHECKING:
    from distributed import LocalCluster


def local_cluster(workers: int) -> LocalCluster:
    """The cluster a sweep starts when given no scheduler: one single-threaded worker process per core. The worker
    processes ignore SIGINT (they inherit SIG_IGN while they start: Python then installs no KeyboardInterrupt
    handler, nor asyncio its own), so a Ctrl-C to the terminal's process group reaches only this process, which
    closes the cluster: no worker prints a KeyboardInterrupt traceback. A Ctrl-C in the seconds the cluster takes
    to start is not seen (press it again once the progress bar shows)."""
    import logging

    from distributed import LocalCluster

    with _sigint_ignored():
        return LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            # no dashboard, and the scheduler's HTTP server (health, metrics) on a free port: None would mean
            # Dask's default 8787, and a warning whenever a notebook's own Dask dashboard holds it
            dashboard_address=":0",
            scheduler_kwargs={"dashboard": False},
            # a failed point is recorded in points.jsonl; a worker whose scheduler closed first (Ctrl-C) would
            # log its heartbeat's traceback at ERROR
            silence_logs=logging.CRITICAL,
        )


@contextlib.contextmanager
def _sigint_ignored():
    """SIGINT ignored inside, so the processes started here inherit SIG_IGN; the handler before it restored on
    the way out. A no-op outside the main thread (signal handlers live there)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def chunk_size(points: int, workers: int) -> int:
    """Points per Dask task: whole rounds of tasks (a multiple of the worker count, >= 4 per worker, <= ~32 points
    each), so no worker is left running an odd last chunk alone (400 points on 2 workers: 14 tasks of <= 29)."""
    rounds = max(4, math.ceil(points / (workers * 32)))
    return max(1, math.ceil(points / (workers * rounds)))


def _run_on_dask(todo, out: Path, scheduler, workers, chunk, progress):
    from distributed import Client, as_completed

    cluster = None
    if scheduler:  # checked by check_scheduler before anything was written
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as e:
            raise SweepFailed(f"--scheduler {scheduler}: cannot connect: {_first_line(e)}") from None
    else:
        try:
            cluster = local_cluster(int(workers or os.cpu_count() or 1))
            client = Client(cluster)
        except Exception as e:  # noqa: BLE001 - a worker killed while starting, no ports, ...
            if cluster is not None:
                with contextlib.suppress(Exception):
                    cluster.close()
            raise SweepFailed(f"the local Dask cluster did not start: {type(e).__name__}: {_first_line(e)}") from None
    try:
        nw = max(1, len(client.scheduler_info().get("workers", {})) or int(workers or 1))
        size = int(chunk) if chunk else chunk_size(len(todo), nw)
        chunks = [todo[i : i + size] for i in range(0, len(todo), size)]
        tag = f"{os.getpid()}-{time.time_ns()}"
        futs = {
            client.submit(evaluate_points, c, retries=2, pure=False, key=f"sweep-{tag}-{i}"): c
            for i, c in enumerate(chunks)
        }
        bar = progress_bar(len(todo), desc="sweep", unit="point", quiet=not progress)
        pf = out / "points.jsonl"
        cut = pf.exists() and pf.stat().st_size and not pf.read_bytes().endswith(b"\n")
        with open(pf, "a") as fh:
            if cut:
                fh.write("\n")  # a line cut by a crash stays alone (ignored when read)
            for fut in _closing(bar, as_completed(list(futs))):
                c = futs[fut]
                try:
                    results = fut.result()
                except Exception as e:  # noqa: BLE001 - e.g. KilledWorker: record every point of the chunk
                    results = [
                        {"index": s["index"], "status": "failed", "error": f"{type(e).__name__}: {e}"} for s in c
                    ]
                for r in results:
                    fh.write(json.dumps(_jsonable(r)) + "\n")
                fh.flush()
                bar.update(len(results))
        bar.close()
    except KeyboardInterrupt:
        quiet_shutdown()
        raise
    finally:
        with contextlib.suppress(Exception):
            client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()


def quiet_shutdown() -> None:
    """Ctrl-C: the Dask client's own shutdown chatter (asyncio cancellations, gather tasks whose AllExit nobody
    retrieved, with their tracebacks) is no news to the user: those loggers say nothing from here on."""
    import logging

    for name in ("distributed", "asyncio", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


def _closing(bar, items):
    """Iterate items; the progress bar is closed however the loop ends (Ctrl-C), so it never prints after the
    last line."""
    try:
        yield from items
    finally:
        bar.close()


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


HANDSHAKE_S = 10.0  # a Dask scheduler sends its handshake as soon as it accepts a connection
HANDSHAKE_MAX = 1 << 20  # bytes: a Dask handshake is a few hundred


def check_scheduler(address: str, timeout_s: float = 5.0) -> str:
    """The Dask scheduler address to connect to (a bare HOST:PORT is tcp://HOST:PORT), checked before anything is
    written: SweepError (bad input, exit 2) for an address that is not tcp://HOST:PORT or a service that is not a
    Dask scheduler (its first bytes are no Dask handshake: Dask's own client would take them for a frame length and
    try to allocate exabytes); SweepFailed (exit 3) when nobody listens there."""
    import socket
    import struct
    from urllib.parse import urlsplit

    text = str(address).strip()
    shown = text if len(text) <= 80 else text[:60] + "..."
    if "://" not in text:
        text = "tcp://" + text
    u = urlsplit(text)
    try:
        host, port = u.hostname, u.port
    except ValueError:
        host = port = None
    if u.scheme != "tcp" or not host or not port or u.path not in ("", "/") or u.query or u.fragment:
        raise SweepError(f"--scheduler {shown}: expected tcp://HOST:PORT (a Dask scheduler's address)")
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as e:
        raise SweepFailed(f"--scheduler {shown}: cannot connect: {e.strerror or e}") from None
    try:
        sock.settimeout(HANDSHAKE_S)
        head = _recv(sock, 8)
        size = struct.unpack("<Q", head)[0] if len(head) == 8 else 0
        if not 0 < size <= HANDSHAKE_MAX or len(_recv(sock, size)) < size:
            raise SweepError(f"--scheduler {shown}: answers, but not as a Dask scheduler (no Dask handshake)")
    except OSError:
        raise SweepError(
            f"--scheduler {shown}: answers, but sent no Dask handshake in {HANDSHAKE_S:g} s (not a Dask scheduler?)"
        ) from None
    finally:
        sock.close()
    return f"tcp://{host}:{port}" if ":" not in host else f"tcp://[{host}]:{port}"


def _recv(sock, n: int) -> bytes:
    """Up to n bytes (fewer only when the peer closes)."""
    buf = b""
    while len(buf) < n:
        part = sock.recv(min(n - len(buf), 65536))
        if not part:
            break
        buf += part
    return buf
