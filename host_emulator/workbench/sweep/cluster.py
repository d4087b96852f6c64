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
    """The cluster a sweep starts when given no scheduler: one single-threaded worker process per core."""
    import logging

    from distributed import LocalCluster

    return LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        # no dashboard, and the scheduler's HTTP server (health, metrics) on a free port: None would mean
        # Dask's default 8787, and a warning whenever a notebook's own Dask dashboard holds it
        dashboard_address=":0",
        scheduler_kwargs={"dashboard": False},
        silence_logs=logging.ERROR,
    )


def chunk_size(points: int, workers: int) -> int:
    """Points per Dask task: whole rounds of tasks (a multiple of the worker count, >= 4 per worker, <= ~32 points
    each), so no worker is left running an odd last chunk alone (400 points on 2 workers: 14 tasks of <= 29)."""
    rounds = max(4, math.ceil(points / (workers * 32)))
    return max(1, math.ceil(points / (workers * rounds)))


def _run_on_dask(todo, out: Path, scheduler, workers, chunk, progress):
    from distributed import Client, as_completed

    cluster = None
    if scheduler:
        _probe_scheduler(scheduler)
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
        import logging

        # Ctrl-C: the cluster's own shutdown chatter (asyncio cancellations) is no news to the user
        for name in ("distributed", "asyncio", "tornado"):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
        raise
    finally:
        with contextlib.suppress(Exception):
            client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()


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


def _probe_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Fail at once (SweepFailed) on a tcp:// scheduler nobody listens at, instead of the client's 20 s wait."""
    import socket
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return
    u = urlsplit(address)
    try:
        host, port = u.hostname, u.port
    except ValueError:
        raise SweepError(f"--scheduler {address}: expected tcp://HOST:PORT") from None
    if not host or not port:
        raise SweepError(f"--scheduler {address}: expected tcp://HOST:PORT")
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as e:
        raise SweepFailed(f"--scheduler {address}: cannot connect: {e.strerror or e}") from None
