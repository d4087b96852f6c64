"""Parameter sweeps on Dask: a grid of scene overrides x noise seeds, run on a local or an existing cluster.

    python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 \
        --grid perturbation.1.torque_Nm=0.005,0.01,0.02,0.04 --seeds 5 --out out/sweep

* Grid: ``KEY=START:STOP:NUM`` (NUM values, both ends included) or ``KEY=V1,V2,...``; KEY is any ``run --set``
  key (params.sigma, perturbation.1.torque_Nm, model_options.noise.band_spread, t_end_s, ...). ``--seeds S``
  adds a coordinate ``seed`` = 0..S-1 set as model_options.noise.seed (give the seeds something to vary,
  e.g. ``--set model_options.noise.band_spread=0.02``).
* Execution: points are cut into chunks; each Dask task evaluates one chunk through
  ``evaluate_points(specs) -> results`` (one place to plug a batched runner in). With no ``--scheduler`` a
  ``distributed.LocalCluster`` with one single-threaded worker process per core is started; with
  ``--scheduler tcp://HOST:PORT`` the sweep runs unchanged on that cluster. Tasks whose worker dies are
  retried by the scheduler; a chunk that still fails has each of its points recorded as failed, with the reason.
* Output in DIR: ``points.jsonl`` (one line per finished point, appended as chunks finish: the sweep is
  resumable, a re-run skips the points already there; ``--retry-failed`` runs failed ones again),
  ``sweep.json`` (the sweep's definition; a re-run with another definition is refused), ``sweep.nc``
  (xarray Dataset, NetCDF 3 through scipy: a coordinate per swept key, observables as variables, ``status``
  and ``error`` per point, provenance and every base-scene parameter as attributes), ``phase_diagram.png``
  (when params.sigma is swept) and ``regime_map.png`` (the first two swept keys, or ``--map KEY KEY``).

Observables per point (NaN where not defined or not produced): domain_walls, pattern_wavelength_cells
(2(N-1)/Z, cells), dominant_mode, pattern_period_cells, amplitude_rad, oscillation_period_s, growth_rate_per_s,
at_rest and steady (1/0), and from the linear theory of the point's parameters: regime,
theory_fastest_lambda_cells, theory_band_lo_cells, theory_band_hi_cells (inf: the band reaches infinitely long
waves), theory_fastest_growth_per_s. Units are attributes of each variable.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import xarray as xr
    from distributed import LocalCluster
    from matplotlib.axes import Axes
    from matplotlib.figure import FigureBase

    from .scene import Scene

OBSERVABLES = {  # name -> units (NaN in the dataset when a run does not report it)
    "domain_walls": "1",
    "pattern_wavelength_cells": "cells",
    "dominant_mode": "1",
    "pattern_period_cells": "cells",
    "amplitude_rad": "rad",
    "oscillation_period_s": "s",
    "growth_rate_per_s": "1/s",
    "at_rest": "1 (true) / 0 (false)",
    "steady": "1 (true) / 0 (false)",
    "theory_fastest_lambda_cells": "cells",
    "theory_band_lo_cells": "cells",
    "theory_band_hi_cells": "cells",
    "theory_fastest_growth_per_s": "1/s",
    "wall_s": "s",
}
STRINGS = ("regime", "status", "error")
MAX_POINTS = 1_000_000  # grid points x seeds: the point list, the store and the dataset stay within memory
COST_SAMPLE = 8  # points whose solver is built to estimate the sweep's cost before any cluster starts


class SweepError(ValueError):
    """A bad sweep definition (grid syntax, keys, output directory)."""


class SweepFailed(RuntimeError):
    """The sweep could not run on (scheduler unreachable, cluster failed to start, interrupted); points already
    finished stay in points.jsonl and a re-run resumes."""


# ---- the grid -------------------------------------------------------------------------------------------


def parse_grid(text: str) -> tuple[str, list]:
    """'KEY=START:STOP:NUM' or 'KEY=V1,V2,...' -> (KEY, values)."""
    from .scene import _value

    if "=" not in text:
        raise SweepError(f"--grid {text!r}: expected KEY=START:STOP:NUM or KEY=V1,V2,...")
    key, spec = (s.strip() for s in text.split("=", 1))
    if not key or not spec:
        raise SweepError(f"--grid {text!r}: empty key or values")
    if spec.count(":") == 2 and "," not in spec:
        a_text, b_text, n_text = spec.split(":")
        try:
            a, b, n = float(_value(a_text)), float(_value(b_text)), int(n_text)
        except (TypeError, ValueError):
            raise SweepError(f"--grid {text!r}: START:STOP:NUM needs two numbers and an integer") from None
        if n < 1 or not (math.isfinite(a) and math.isfinite(b)):
            raise SweepError(f"--grid {text!r}: NUM must be >= 1 and START, STOP finite")
        if n > MAX_POINTS:
            raise SweepError(f"--grid {text!r}: NUM = {n} exceeds the sweep's {MAX_POINTS} points")
        return key, [float(v) for v in np.linspace(a, b, n)]
    vals = [_value(v) for v in spec.split(",") if v.strip()]
    if not vals:
        raise SweepError(f"--grid {text!r}: no values")
    if len(set(map(repr, vals))) != len(vals):
        raise SweepError(f"--grid {text!r}: repeated values")
    return key, vals


def _fmt_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


def point_specs(scene: str, grid: dict, seeds: int | None, fixed: Sequence[str] = ()) -> tuple[list[dict], dict]:
    """Every grid point as a spec {"index", "scene", "overrides", "coords"}; and the coordinate axes."""
    axes = {k: list(v) for k, v in grid.items()}
    if seeds:
        axes["seed"] = list(range(int(seeds)))
    specs = []
    for i, combo in enumerate(itertools.product(*axes.values())):
        coords = dict(zip(axes, combo))
        over = list(fixed) + [f"{k}={_fmt_value(v)}" for k, v in coords.items() if k != "seed"]
        if "seed" in coords:
            over.append(f"model_options.noise.seed={coords['seed']}")
        specs.append({"index": i, "scene": scene, "overrides": over, "coords": coords})
    return specs, axes


# ---- one chunk of points: the task each Dask worker runs ------------------------------------------------


def _num(v):
    if v is None:
        return float("nan")
    if isinstance(v, bool):
        return float(v)
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def evaluate_points(specs: list[dict]) -> list[dict]:
    """Run each point spec and return one result dict per spec, in order; a failing point gives
    {"status": "failed", "error": "<Type>: <message>"} instead of raising. The points of a chunk run together
    in one compiled call (host_emulator.batch.run_batch: hil lattices batched, bit-identical to run_scene;
    other models one by one), so a point costs no Python per control tick."""
    from .batch import run_batch
    from .cli import summarize
    from .limits import scene_cost
    from .scene import load_scene

    out: list[dict] = []
    loaded = []
    for spec in specs:
        r = {"index": spec["index"], "status": "ok", "error": ""}
        try:
            sc = load_scene(spec["scene"], spec["overrides"])
            scene_cost(sc)  # the point's own guard: a point too long is recorded as failed, with the figure
            loaded.append((r, sc))
        except Exception as e:  # noqa: BLE001 - a failing point is recorded, never dropped
            r["status"], r["error"], r["wall_s"] = "failed", f"{type(e).__name__}: {e}", 0.0
        out.append(r)
    try:
        results = run_batch([sc for _, sc in loaded], errors="return")
    except Exception as e:  # noqa: BLE001 - e.g. a point the batch refuses to build
        results = [e] * len(loaded)
    for (r, sc), res in zip(loaded, results):
        try:
            if isinstance(res, BaseException):
                raise res
            s = summarize(sc, res)
            for k in OBSERVABLES:
                if k in s:
                    r[k] = _num(s[k])
            d = s.get("dispersion") or {}
            band = d.get("unstable_band_cells")
            r["regime"] = str(d.get("regime") or "")
            r["theory_fastest_lambda_cells"] = _num(d.get("fastest_lambda_cells"))
            r["theory_fastest_growth_per_s"] = _num(d.get("fastest_growth_per_s"))
            r["theory_band_lo_cells"] = _num(band[0]) if band else float("nan")
            r["theory_band_hi_cells"] = (float("inf") if band[1] is None else _num(band[1])) if band else float("nan")
            r["wall_s"] = float(res.wall_s)
        except Exception as e:  # noqa: BLE001 - a failing point is recorded, never dropped
            r["status"], r["error"] = "failed", f"{type(e).__name__}: {e}"
            r.setdefault("wall_s", 0.0)
    return out


# ---- the store: points.jsonl + sweep.json, resumable ----------------------------------------------------


def _jsonable(r: dict) -> dict:
    return {
        k: (
            None if isinstance(v, float) and math.isnan(v) else ("inf" if isinstance(v, float) and math.isinf(v) else v)
        )
        for k, v in r.items()
    }


def _from_json(r: dict) -> dict:
    return {k: (float("nan") if v is None else (float("inf") if v == "inf" else v)) for k, v in r.items()}


def load_done(out: Path) -> dict[int, dict]:
    done: dict[int, dict] = {}
    f = out / "points.jsonl"
    if f.exists():
        for line in f.read_text().splitlines():
            try:
                r = _from_json(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line cut by a crash: that point runs again
            done[int(r["index"])] = r  # the latest line for a point wins (a retried failure)
    return done


# ---- the driver -----------------------------------------------------------------------------------------


def sweep(
    scene: str = "default",
    grid: dict | None = None,
    *,
    seeds: int | None = None,
    out: str | Path = "out/sweep",
    fixed: Sequence[str] = (),
    scheduler: str | None = None,
    workers: int | None = None,
    chunk: int | None = None,
    progress: bool = True,
    retry_failed: bool = False,
    plots: bool = True,
    map_keys: Sequence[str] | None = None,
) -> xr.Dataset:
    """Run the sweep (see module docstring) and return its xarray Dataset (also written to out/sweep.nc)."""
    from .api import load_scene

    grid = dict(grid or {})
    for k, v in grid.items():
        if not isinstance(v, (list, tuple)) or not v:
            raise SweepError(f"grid[{k!r}]: expected a non-empty list of values")
    if seeds is not None and (isinstance(seeds, bool) or int(seeds) < 1):
        raise SweepError(f"seeds = {seeds!r}: expected a positive integer")
    n_points = math.prod(len(v) for v in grid.values()) * int(seeds or 1)
    if n_points > MAX_POINTS:
        raise SweepError(
            f"the grid is {' x '.join(str(len(v)) for v in grid.values())}{f' x {seeds} seeds' if seeds else ''} = "
            f"{n_points} points (limit {MAX_POINTS}): fewer values or seeds"
        )
    scene_name = str(scene)
    specs, axes = point_specs(scene_name, grid, seeds, list(fixed))
    base = load_scene(scene_name, list(fixed))
    load_scene(scene_name, specs[0]["overrides"])  # a bad key fails here, before anything is written
    out = Path(out)
    from .outpaths import check_out_dir

    problem = check_out_dir(out)
    if problem:
        raise SweepError(problem)
    cost = estimate_cost(specs)  # a bad key, a point too long or a sweep too large fails here, before any cluster
    if progress:
        print(f"sweep: {len(specs)} points, about {cost:.3g} cell steps in all", file=sys.stderr)
    definition = {"scene": scene_name, "fixed": list(fixed), "axes": {k: list(v) for k, v in axes.items()}}
    dfile = out / "sweep.json"
    if dfile.exists():
        old = json.loads(dfile.read_text())
        if {k: old.get(k) for k in definition} != json.loads(json.dumps(definition)):
            raise SweepError(f"{out} holds a different sweep ({dfile}); choose another --out or delete it")
    else:
        dfile.write_text(json.dumps(definition, indent=1) + "\n")
    done = load_done(out)
    todo = [s for s in specs if s["index"] not in done or (retry_failed and done[s["index"]].get("status") != "ok")]
    if todo:
        _run_on_dask(todo, out, scheduler, workers, chunk, progress)
    done = load_done(out)
    ds = to_dataset(specs, axes, done, base, definition)
    ds.to_netcdf(out / "sweep.nc", engine="scipy")
    if plots:
        files = []
        if "params.sigma" in axes:
            _save(plot_phase_diagram(ds, base), out / "phase_diagram.png")
            files.append("phase_diagram.png")
        keys = list(map_keys or [k for k in axes if len(axes[k]) > 1][:2])
        if len(keys) == 2:
            _save(plot_regime_map(ds, keys[0], keys[1]), out / "regime_map.png")
    return ds


def estimate_cost(specs: list[dict]) -> float:
    """The sweep's cell steps, from COST_SAMPLE points spread over the grid (first and last included), each built
    as its run would be (limits.scene_cost: every preset and automatic step resolved). Raises RunTooLarge for a
    sampled point that is too long on its own or a sweep over the batch limit (the figure in the message)."""
    from .limits import RunTooLarge, batch_budget, scene_cost
    from .scene import load_scene

    n = len(specs)
    k = min(n, COST_SAMPLE)
    picks = sorted({round(i * (n - 1) / max(1, k - 1)) for i in range(k)})
    costs = []
    for i in picks:
        try:
            costs.append(scene_cost(load_scene(specs[i]["scene"], specs[i]["overrides"])))
        except RunTooLarge as e:
            raise SweepError(f"point {i} {specs[i]['coords']}: {e}") from None
        except (KeyError, ValueError):  # a bad point is recorded as failed when it runs, as every bad point is
            continue
    if not costs:
        load_scene(specs[0]["scene"], specs[0]["overrides"])  # every sampled point is bad: say why (bad key...)
        return 0.0
    total = sum(costs) / len(costs) * n
    problem = batch_budget(total, f"the sweep of {n} points (about {total / n:.3g} cell steps each)")
    if problem:
        raise RunTooLarge(problem)
    return total


def _save(fig, path):
    fig.savefig(path, dpi=110)
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close(fig)


def local_cluster(workers: int) -> LocalCluster:
    """The cluster a sweep starts when given no scheduler: one single-threaded worker process per core."""
    import logging

    from distributed import LocalCluster

    return LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
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
    from tqdm import tqdm

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
        bar = tqdm(total=len(todo), unit="point", desc="sweep", disable=not progress, file=sys.stderr)
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


def to_dataset(specs: list[dict], axes: dict, done: dict, base: Scene, definition: dict) -> xr.Dataset:
    """The xarray Dataset of a sweep: dims = swept keys (+ seed), observables as variables."""
    import xarray as xr

    from .api import netcdf_attrs
    from .provenance import provenance

    shape = tuple(len(v) for v in axes.values())
    dims = tuple(axes)
    data = {k: np.full(shape, np.nan) for k in OBSERVABLES}
    strs = {k: np.full(shape, "", dtype=object) for k in STRINGS}
    strs["status"][...] = "pending"
    for s in specs:
        ix = np.unravel_index(s["index"], shape)
        r = done.get(s["index"])
        if r is None:
            continue
        for k in OBSERVABLES:
            if k in r:
                data[k][ix] = _num(r[k])
        for k in STRINGS:
            strs[k][ix] = str(r.get(k, "") or "")
    vars_: dict[str, tuple] = {k: (dims, v, {"units": u}) for k, v in data.items() for u in [OBSERVABLES[k]]}
    vars_.update({k: (dims, v.astype(str)) for k, v in strs.items()})
    coords = {}
    for k, v in axes.items():
        arr = np.asarray(v)
        coords[k] = (k, arr if arr.dtype.kind in "ifu" else arr.astype(str))
    ds = xr.Dataset(vars_, coords=coords)
    ds.attrs.update(netcdf_attrs(base))
    ds.attrs.update({f"provenance.{k}": v for k, v in provenance().items()})
    ds.attrs["sweep.definition"] = json.dumps(definition)
    ds.attrs["sweep.points"] = int(np.prod(shape))
    ds.attrs["sweep.failed"] = int((strs["status"] == "failed").sum())
    return ds


# ---- plots ----------------------------------------------------------------------------------------------


def plot_phase_diagram(
    ds: xr.Dataset, base: Scene | None = None, *, ax: Axes | None = None, inertia: bool | None = None
) -> FigureBase:
    """Selected wavelength (2(N-1)/Z, cells) of every point against sigma, with the linear theory's unstable
    band (shaded) and fastest wavelength (line) of the base scene's parameters at each sigma. Returns the Figure."""
    from .analysis.stability import dispersion
    from .plots import new_figure

    if ax is None:
        fig = new_figure(figsize=(7.5, 4.8), constrained_layout=True)
        ax = fig.add_subplot(111)
    sig = np.asarray(ds["params.sigma"].values, dtype=float)
    lam = ds["pattern_wavelength_cells"].transpose("params.sigma", ...).values.reshape(len(sig), -1)
    xs = np.repeat(sig, lam.shape[1])
    ax.plot(xs, lam.ravel(), "o", ms=3, alpha=0.5, color="k", label="sweep: selected wavelength 2(N-1)/Z")
    if base is not None:
        import dataclasses

        inert = base.options.inertia and base.model != "continuum" if inertia is None else inertia
        sg = np.linspace(sig.min(), sig.max(), max(60, len(sig)))
        lo, hi, fast = [], [], []
        for s in sg:
            d = dispersion(
                dataclasses.replace(base.params, sigma=float(s)), inertia=inert, n_cells=base.cells, n_kappa=600
            )
            b = d.get("unstable_band_cells")
            lo.append(b[0] if b else np.nan)
            hi.append((b[1] if b[1] is not None else 1e3) if b else np.nan)
            fast.append(d.get("fastest_lambda_cells") or np.nan)
        ax.fill_between(sg, lo, hi, color="C0", alpha=0.15, label="linear theory: unstable band")
        ax.plot(sg, fast, color="C0", lw=1.5, label="linear theory: fastest wavelength")
    n = int(ds.attrs.get("cells", 16))
    ax.set_ylim(1.5, 4 * n)
    ax.set_yscale("log")
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_yticks([2, 3, 5, 7.5, 10, 15, 20, 30, 60])
    ax.set_xlabel("sigma (N·m/rad)")
    ax.set_ylabel("wavelength (cells)")
    ax.set_title(
        f"phase diagram: {ds.attrs.get('scene', '')}, {ds.sizes.get('seed', 1)} seed(s) per point", fontsize=10
    )
    ax.legend(fontsize=7, loc="upper right")
    return ax.figure


OUTCOMES = ("rest", "pattern", "moving", "failed")


def outcome(ds: xr.Dataset) -> np.ndarray:
    """Per point: 0 rest, 1 pattern (steady, domain walls), 2 moving (not steady), 3 failed, -1 pending."""
    st = ds["status"].values.astype(str)
    rest = ds["at_rest"].values == 1
    steady = ds["steady"].values == 1
    code = np.where(rest, 0, np.where(steady, 1, 2))
    code = np.where(st == "failed", 3, np.where(st == "pending", -1, code))
    return code


def plot_regime_map(ds: xr.Dataset, xkey: str, ykey: str, *, ax: Axes | None = None) -> FigureBase:
    """The most frequent outcome (rest / pattern / moving / failed) over the other swept keys, on xkey x ykey,
    with the linear theory's regime of each point named in the title's legend. Returns the Figure."""
    from matplotlib.colors import ListedColormap

    from .plots import new_figure

    for k in (xkey, ykey):
        if k not in ds.dims:
            raise SweepError(f"regime map: {k!r} is not a swept key; swept: {', '.join(map(str, ds.dims))}")
    if ax is None:
        fig = new_figure(figsize=(7, 4.8), constrained_layout=True)
        ax = fig.add_subplot(111)
    import xarray as xr

    code = xr.DataArray(outcome(ds), dims=ds["status"].dims).transpose(ykey, xkey, ...)
    c = code.values.reshape(code.shape[0], code.shape[1], -1)
    mode = np.full(c.shape[:2], -1)
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            v = c[i, j][c[i, j] >= 0]
            if len(v):
                mode[i, j] = np.bincount(v, minlength=4).argmax()
    cmap = ListedColormap(["0.85", "C0", "C1", "C3"])
    xv, yv = np.asarray(ds[xkey].values), np.asarray(ds[ykey].values)
    ax.imshow(
        np.ma.masked_less(mode, 0),
        origin="lower",
        aspect="auto",
        cmap=cmap,
        vmin=-0.5,
        vmax=3.5,
        interpolation="nearest",
    )
    ax.set_xticks(range(len(xv)))
    ax.set_xticklabels(
        [f"{v:.3g}" if isinstance(v, (float, np.floating)) else str(v) for v in xv],
        rotation=90 if len(xv) > 8 else 0,
        fontsize=7,
    )
    ax.set_yticks(range(len(yv)))
    ax.set_yticklabels([f"{v:.3g}" if isinstance(v, (float, np.floating)) else str(v) for v in yv], fontsize=7)
    if len(xv) > 16:
        for lab in ax.get_xticklabels()[1::2]:
            lab.set_visible(False)
    from matplotlib.patches import Patch

    ax.legend(
        handles=[Patch(color=cmap(i), label=o) for i, o in enumerate(OUTCOMES)],
        fontsize=7,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
    )
    ax.set_xlabel(xkey)
    ax.set_ylabel(ykey)
    ax.set_title(f"regime map (most frequent outcome): {ds.attrs.get('scene', '')}", fontsize=10)
    return ax.figure


# ---- command line ---------------------------------------------------------------------------------------

EPILOG = """examples:
  python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 \\
      --grid perturbation.1.torque_Nm=0.005,0.01,0.02,0.04 --seeds 5 \\
      --set model_options.noise.band_spread=0.02 --out out/sweep
  python -m host_emulator sweep default --grid params.sigma=0.05,0.07 --set t_end_s=2 --workers 2 --out out/s2
  dask scheduler --port 8786 &  dask worker tcp://127.0.0.1:8786 --nthreads 1 &
  python -m host_emulator sweep default --grid params.sigma=0.04:0.12:9 --scheduler tcp://127.0.0.1:8786 --out out/s3

Re-running the same command resumes: points already in DIR/points.jsonl are skipped.
Exit codes: 0 every point ran, 1 some points failed (recorded in the dataset), 2 bad input (grid, keys, output
directory, a sweep over the size limits: the figure is given), 3 the sweep could not run on (scheduler unreachable,
cluster did not start, interrupted, write error; finished points are kept and a re-run resumes)."""


def sweep_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator sweep",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run a grid of scene overrides x noise seeds on Dask; write one "
        "xarray dataset (sweep.nc), the phase diagram and a regime map.",
    )
    ap.add_argument("scene", help="shipped scene name or .toml path (see `python -m host_emulator scenes`)")
    ap.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY=SPEC",
        required=True,
        help="a swept key: KEY=START:STOP:NUM (NUM values, ends included) or KEY=V1,V2,...; repeatable",
    )
    ap.add_argument(
        "--seeds",
        type=int,
        default=None,
        metavar="S",
        help="add a coordinate seed = 0..S-1 (sets model_options.noise.seed)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a fixed override for every point, as in `run --set` (e.g. t_end_s=2)",
    )
    ap.add_argument("--out", required=True, metavar="DIR", help="output directory (resumable: re-run to continue)")
    ap.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="an existing Dask scheduler (default: start a local cluster)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local cluster: worker processes (default: the machine's cores)",
    )
    ap.add_argument("--chunk", type=int, default=None, metavar="K", help="points per Dask task (default: automatic)")
    ap.add_argument("--retry-failed", action="store_true", help="run the points recorded as failed again")
    ap.add_argument(
        "--map",
        nargs=2,
        default=None,
        metavar=("XKEY", "YKEY"),
        help="the regime map's axes (default: the first two swept keys with more than one value)",
    )
    ap.add_argument("--no-plots", action="store_true", help="skip phase_diagram.png and regime_map.png")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    from .models import ConfigError

    try:
        if args.workers is not None and args.workers < 1:
            raise SweepError("--workers must be >= 1")
        if args.chunk is not None and args.chunk < 1:
            raise SweepError("--chunk must be >= 1")
        grid = dict(parse_grid(g) for g in args.grid)
        ds = sweep(
            args.scene,
            grid,
            seeds=args.seeds,
            out=args.out,
            fixed=args.set,
            scheduler=args.scheduler,
            workers=args.workers,
            chunk=args.chunk,
            progress=not args.quiet,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            map_keys=args.map,
        )
    except (SweepError, ConfigError, KeyError) as e:
        print(f"error: {e.args[0] if isinstance(e, KeyError) and e.args else e}", file=sys.stderr)
        return 2
    except SweepFailed as e:
        print(f"error: sweep failed: {e}; finished points are kept in {args.out}/points.jsonl", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(
            f"sweep: interrupted; finished points are kept in {args.out}/points.jsonl (the same command resumes)",
            file=sys.stderr,
        )
        return 3
    except OSError as e:
        print(f"error: sweep failed: cannot write {args.out}: {e.strerror or e}", file=sys.stderr)
        return 3
    st = ds["status"].values.astype(str)
    failed = int((st == "failed").sum())
    print(f"sweep: {st.size} points, {int((st == 'ok').sum())} ok, {failed} failed; wrote {args.out}/sweep.nc")
    if failed:
        errs = ds["error"].values.astype(str)[st == "failed"]
        print(f"  first failure: {errs[0]}", file=sys.stderr)
    return 1 if failed else 0
