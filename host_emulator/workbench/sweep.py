"""Parameter sweeps on Dask: a grid of scene overrides x noise seeds, run on a local or an existing cluster.

    python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 \
        --grid perturbation.1.torque_Nm=0.005,0.01,0.02,0.04 --seeds 5 --out out/sweep

* Grid: ``KEY=START:STOP:NUM`` (NUM values, both ends included, computed exactly: 0.04:0.12:41 gives 0.056, not
  0.055999999999999994; fractions such as 6/125 allowed) or ``KEY=V1,V2,...``; KEY is any ``run --set`` key
  (params.sigma, perturbation.1.torque_Nm, model_options.noise.band_spread, t_end_s, ...). ``--seeds S``
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
  (xarray Dataset, NetCDF 3 through scipy: a coordinate per swept key, named plainly for ``.sel`` (``sigma``,
  ``torque_Nm``; the full key in the coordinate's ``key`` attribute), observables as variables, ``status``
  and ``error`` per point, provenance and every base-scene parameter as attributes), ``phase_diagram.png``
  (when params.sigma is swept) and ``regime_map.png`` (the first two swept keys, or ``--map KEY KEY``).

Observables per point (NaN where not defined or not produced): domain_walls, pattern_wavelength_cells
(2(N-1)/Z, cells), dominant_mode, pattern_period_cells, amplitude_rad, oscillation_period_s, growth_rate_per_s,
at_rest and steady (1/0), outcome (rest / pattern / oscillation / moving / failed), and from the linear theory
of the model that runs, at the point's parameters: regime (docs/analysis.md#regimes), theory_fastest_lambda_cells,
theory_fastest_growth_per_s and, over a dimension ``band`` (one entry per unstable interval, NaN-padded),
theory_band_lo_cells, theory_band_hi_cells (inf: the interval reaches infinitely long waves) and
theory_band_kind (stationary / oscillatory). Units are attributes of each variable.
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
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import xarray as xr
    from distributed import LocalCluster
    from matplotlib.axes import Axes
    from matplotlib.figure import FigureBase

    from ..scene import Scene
    from .api import Overrides

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
    "theory_fastest_growth_per_s": "1/s",
    "wall_s": "s",
}
BANDS = {"theory_band_lo_cells": "cells", "theory_band_hi_cells": "cells"}  # per unstable interval (dim band)
STRINGS = ("regime", "outcome", "status", "error")
OUTCOMES = ("rest", "pattern", "oscillation", "moving", "failed")
MAX_POINTS = 1_000_000  # grid points x seeds: the point list, the store and the dataset stay within memory
COST_SAMPLE = 8  # points whose solver is built to estimate the sweep's cost before any cluster starts


class SweepError(ValueError):
    """A bad sweep definition (grid syntax, keys, output directory)."""


class SweepFailed(RuntimeError):
    """The sweep could not run on (scheduler unreachable, cluster failed to start, interrupted); points already
    finished stay in points.jsonl and a re-run resumes."""


# ---- the grid -------------------------------------------------------------------------------------------


def _exact_range(a_text: str, b_text: str, n: int) -> list[float]:
    """NUM values from START to STOP, both included, each the float nearest the exact decimal (or fraction) value:
    0.04:0.12:41 gives 0.056 where linspace gives 0.055999999999999994 (so ds.sel(sigma=0.056) finds it)."""
    from fractions import Fraction

    a, b = Fraction(a_text.strip()), Fraction(b_text.strip())
    if n == 1:
        return [float(a)]
    return [float(a + (b - a) * i / (n - 1)) for i in range(n)]


def parse_grid(text: str) -> tuple[str, list]:
    """'KEY=START:STOP:NUM' or 'KEY=V1,V2,...' -> (KEY, values)."""
    from ..scene import _value

    if "=" not in text:
        raise SweepError(f"--grid {text!r}: expected KEY=START:STOP:NUM or KEY=V1,V2,...")
    key, spec = (s.strip() for s in text.split("=", 1))
    if not key or not spec:
        raise SweepError(f"--grid {text!r}: empty key or values")
    if spec.count(":") == 2 and "," not in spec:
        a_text, b_text, n_text = spec.split(":")
        try:
            n = int(n_text)
        except ValueError:
            raise SweepError(f"--grid {text!r}: START:STOP:NUM needs two numbers and an integer") from None
        if n > MAX_POINTS:  # before the values are made: NUM = 1e8 would fill memory
            raise SweepError(f"--grid {text!r}: NUM = {n} exceeds the sweep's {MAX_POINTS} points")
        try:
            vals = _exact_range(a_text, b_text, max(n, 1))
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            raise SweepError(f"--grid {text!r}: START:STOP:NUM needs two numbers and an integer") from None
        if n < 1 or not all(math.isfinite(v) for v in vals):
            raise SweepError(f"--grid {text!r}: NUM must be >= 1 and START, STOP finite")
        return key, vals
    vals = [_value(v) for v in spec.split(",") if v.strip()]
    if not vals:
        raise SweepError(f"--grid {text!r}: no values")
    if len(set(map(repr, vals))) != len(vals):
        raise SweepError(f"--grid {text!r}: repeated values")
    return key, vals


def coord_names(keys) -> dict[str, str]:
    """Plain coordinate names for swept keys, usable with ds.sel(...) and as attributes: the last part of the key
    (params.sigma -> sigma, perturbation.1.torque_Nm -> torque_Nm), the whole key with '_' for '.' where two
    keys would share a name or a name is a variable's (regime, status, ...)."""
    keys = list(keys)
    last = [k.split(".")[-1] for k in keys]
    reserved = set(OBSERVABLES) | set(BANDS) | set(STRINGS) | {"seed", "band", "theory_band_kind"}
    out = {}
    for k, name in zip(keys, last):
        if k == "seed":
            out[k] = "seed"
        elif last.count(name) > 1 or name in reserved or not name.isidentifier():
            out[k] = k.replace(".", "_")
        else:
            out[k] = name
    return out


def _coord(ds: xr.Dataset, key: str) -> str | None:
    """The coordinate of a swept key (by its 'key' attribute, or an old dataset's coordinate named by the key)."""
    for name, c in ds.coords.items():
        if c.attrs.get("key") == key:
            return str(name)
    return key if key in ds.coords else None


def _fmt_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


def point_specs(scene: str | dict, grid: dict, seeds: int | None, fixed: Sequence[str] = ()) -> tuple[list[dict], dict]:
    """Every grid point as a spec {"index", "scene", "overrides", "coords"}; and the coordinate axes. scene: a shipped
    name / TOML path, or a scene table (scene.scene_table) that workers rebuild."""
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


def _load_spec(spec: dict):
    from ..scene import apply_overrides, load_scene, scene_from_dict

    if isinstance(spec["scene"], dict):
        return scene_from_dict(apply_overrides(spec["scene"], spec["overrides"]), "")
    return load_scene(spec["scene"], spec["overrides"])


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


def outcome_of(r: dict) -> str:
    """A point's outcome from its observables: rest, pattern (steady with domain walls), oscillation (a temporal
    period found, not at rest), moving (neither), failed."""
    if r.get("status") == "failed":
        return "failed"
    if r.get("at_rest") == 1:
        return "rest"
    if math.isfinite(_num(r.get("oscillation_period_s"))):
        return "oscillation"
    if r.get("steady") == 1 and _num(r.get("domain_walls")) > 0:
        return "pattern"
    return "moving"


def evaluate_points(specs: list[dict]) -> list[dict]:
    """Run each point spec and return one result dict per spec, in order; a failing point gives
    {"status": "failed", "error": "<Type>: <message>"} instead of raising. The points of a chunk run together
    in one compiled call (host_emulator.workbench.batch.run_batch: hil lattices batched, bit-identical to run_scene;
    other models one by one), so a point costs no Python per control tick."""
    from ..analysis.summary import summarize
    from ..limits import scene_cost
    from .batch import run_batch

    out: list[dict] = []
    loaded = []
    for spec in specs:
        r = {"index": spec["index"], "status": "ok", "error": ""}
        try:
            sc = _load_spec(spec)
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
            r["regime"] = str(d.get("regime") or "")
            r["theory_fastest_lambda_cells"] = _num(d.get("fastest_lambda_cells"))
            r["theory_fastest_growth_per_s"] = _num(d.get("fastest_growth_per_s"))
            r["theory_bands"] = [
                [
                    _num(iv["lambda_cells"][0]),
                    "inf" if iv["lambda_cells"][1] is None else _num(iv["lambda_cells"][1]),
                    iv["kind"],
                ]
                for iv in d.get("unstable_intervals") or []
            ]
            r["wall_s"] = float(res.wall_s)
        except Exception as e:  # noqa: BLE001 - a failing point is recorded, never dropped
            r["status"], r["error"] = "failed", f"{type(e).__name__}: {e}"
            r.setdefault("wall_s", 0.0)
        r["outcome"] = outcome_of(r)
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
    scene: str | Scene = "default",
    grid: Mapping[str, Iterable] | None = None,
    *,
    seeds: int | None = None,
    out: str | Path = "out/sweep",
    fixed: Overrides = (),
    accuracy: str | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    chunk: int | None = None,
    progress: bool = True,
    retry_failed: bool = False,
    plots: bool = True,
    map_keys: Sequence[str] | None = None,
) -> xr.Dataset:
    """Run the sweep (see module docstring) and return its xarray Dataset (also written to out/sweep.nc).

    scene and fixed take what host_emulator.run takes (a shipped name, a .toml path or a Scene; overrides as
    {"params.sigma": "6/125"} or ["KEY=VALUE", ...]); grid: {key: values} (a list, a range, a numpy array);
    progress: a bar on stderr (shown on a terminal only)."""
    from ..scene import _value, scene_table
    from .api import override_list

    grid = {
        str(k): [_value(x) if isinstance(x, str) else x for x in (v.tolist() if isinstance(v, np.ndarray) else v)]
        for k, v in dict(grid or {}).items()
    }  # string values read as on the command line: "6/125" is a fraction
    for k, v in grid.items():
        if not v:
            raise SweepError(f"grid[{k!r}]: expected a non-empty list of values")
    if seeds is not None and (isinstance(seeds, bool) or int(seeds) < 1):
        raise SweepError(f"seeds = {seeds!r}: expected a positive integer")
    sizes = [len(list(v)) for v in grid.values()]
    n_points = math.prod(sizes) * int(seeds or 1)  # before the point list is built
    if n_points > MAX_POINTS:
        raise SweepError(
            f"the grid is {' x '.join(map(str, sizes))}{f' x {seeds} seeds' if seeds else ''} = "
            f"{n_points} points (limit {MAX_POINTS}): fewer values or seeds"
        )
    fixed = override_list(fixed) + ([f'accuracy="{accuracy}"'] if accuracy else [])
    if isinstance(scene, (str, Path)):
        scene_ref: str | dict = str(scene)
    elif hasattr(scene, "as_dict"):
        scene_ref = scene_table(scene)  # a Scene object: workers rebuild it from its table
    else:
        raise SweepError(f"scene = {scene!r}: expected a scene name, a .toml path or a Scene")
    specs, axes = point_specs(scene_ref, grid, seeds, fixed)
    base = _load_spec({"scene": scene_ref, "overrides": fixed})
    _load_spec(specs[0])  # a bad key fails here, before anything is written
    out = Path(out)
    from ..outpaths import check_out_dir

    problem = check_out_dir(out)
    if problem:
        raise SweepError(problem)
    cost = estimate_cost(specs)  # a bad key, a point too long or a sweep too large fails here, before any cluster
    if progress:
        print(f"sweep: {len(specs)} points, about {cost:.3g} cell steps in all", file=sys.stderr)
    definition = {"scene": scene_ref, "fixed": list(fixed), "axes": {k: list(v) for k, v in axes.items()}}
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
        if "params.sigma" in axes:
            _save(plot_phase_diagram(ds, base), out / "phase_diagram.png")
        keys = list(map_keys or [k for k in axes if len(axes[k]) > 1][:2])
        if len(keys) == 2:
            names = coord_names(axes)
            _save(plot_regime_map(ds, names.get(keys[0], keys[0]), names.get(keys[1], keys[1])), out / "regime_map.png")
    return ds


def estimate_cost(specs: list[dict]) -> float:
    """The sweep's cell steps, from COST_SAMPLE points spread over the grid (first and last included), each built
    as its run would be (limits.scene_cost: every preset and automatic step resolved). Raises RunTooLarge for a
    sampled point that is too long on its own or a sweep over the batch limit (the figure in the message)."""
    from ..limits import RunTooLarge, batch_budget, scene_cost

    n = len(specs)
    k = min(n, COST_SAMPLE)
    picks = sorted({round(i * (n - 1) / max(1, k - 1)) for i in range(k)})
    costs = []
    for i in picks:
        try:
            costs.append(scene_cost(_load_spec(specs[i])))
        except RunTooLarge as e:
            raise SweepError(f"point {i} {specs[i]['coords']}: {e}") from None
        except (KeyError, ValueError):  # a bad point is recorded as failed when it runs, as every bad point is
            continue
    if not costs:
        _load_spec(specs[0])  # every sampled point is bad: say why (bad key...)
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

    from ..progress import bar as progress_bar

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


def to_dataset(specs: list[dict], axes: dict, done: dict, base: Scene, definition: dict) -> xr.Dataset:
    """The xarray Dataset of a sweep: one dimension per swept key (plain names, the key in the coordinate's 'key'
    attribute; + seed), observables as variables, the theory's unstable intervals over a dimension 'band'."""
    import xarray as xr

    from ..provenance import provenance
    from .api import netcdf_attrs

    shape = tuple(len(v) for v in axes.values())
    names = coord_names(axes)
    dims = tuple(names[k] for k in axes)
    nb = max([1] + [len(r.get("theory_bands") or []) for r in done.values()])
    data = {k: np.full(shape, np.nan) for k in OBSERVABLES}
    bands = {k: np.full(shape + (nb,), np.nan) for k in BANDS}
    kinds = np.full(shape + (nb,), "", dtype=object)
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
        for b, (lo, hi, kind) in enumerate(r.get("theory_bands") or []):
            bands["theory_band_lo_cells"][ix + (b,)] = _num(lo)
            bands["theory_band_hi_cells"][ix + (b,)] = float("inf") if hi in ("inf", None) else _num(hi)
            kinds[ix + (b,)] = kind
        for k in STRINGS:
            strs[k][ix] = str(r.get(k, "") or "")
        if not strs["outcome"][ix]:
            strs["outcome"][ix] = outcome_of(r)  # points stored before outcomes were
    vars_: dict[str, tuple] = {k: (dims, v, {"units": OBSERVABLES[k]}) for k, v in data.items()}
    vars_.update({k: (dims + ("band",), v, {"units": BANDS[k]}) for k, v in bands.items()})
    vars_["theory_band_kind"] = (dims + ("band",), kinds.astype(str), {"long_name": "stationary / oscillatory"})
    vars_.update({k: (dims, v.astype(str)) for k, v in strs.items()})
    coords = {}
    for k, v in axes.items():
        arr = np.asarray(v)
        coords[names[k]] = (names[k], arr if arr.dtype.kind in "ifu" else arr.astype(str), {"key": k})
    ds = xr.Dataset(vars_, coords=coords)
    ds.attrs.update(netcdf_attrs(base))
    ds.attrs.update({f"provenance.{k}": v for k, v in provenance().items()})
    ds.attrs["sweep.definition"] = json.dumps(definition)
    ds.attrs["sweep.points"] = int(np.prod(shape))
    ds.attrs["sweep.failed"] = int((strs["status"] == "failed").sum())
    ds.attrs["source"] = f"emulator:{base.model}"
    return ds


# ---- plots ----------------------------------------------------------------------------------------------


OUTCOME_STYLE = {  # outcome -> (marker, colour, label) in the phase diagram
    "pattern": ("o", "k", "pattern: selected wavelength 2(N-1)/Z"),
    "rest": ("v", "0.45", "rest (drawn at the bottom)"),
    "oscillation": ("^", "C3", "oscillation (drawn at the top)"),
    "moving": ("s", "C1", "still moving at the end (drawn at the top)"),
    "failed": ("x", "C3", "failed (drawn at the bottom)"),
}


def theory_bands_over(base: Scene, sigmas: np.ndarray) -> dict:
    """The linear theory of the base scene's model at each sigma: {'stationary': [(lo, hi), ...] per sigma,
    'oscillatory': ..., 'fastest': the fastest stationary wavelength, 'regime': ...}, hi inf for an interval reaching
    the longest waves."""
    import dataclasses

    from ..analysis.stability import dispersion, theory_of

    out: dict = {"stationary": [], "oscillatory": [], "fastest": [], "regime": []}
    for sg in sigmas:
        p = dataclasses.replace(base.params, sigma=float(sg))
        d = dispersion(p, theory=theory_of(base.model, p, base.options.inertia), n_cells=base.cells, n_kappa=600)
        for kind in ("stationary", "oscillatory"):
            out[kind].append(
                [
                    (iv["lambda_cells"][0], iv["lambda_cells"][1] or math.inf)
                    for iv in d["unstable_intervals"]
                    if iv["kind"] == kind
                ]
            )
        stat = [iv for iv in d["unstable_intervals"] if iv["kind"] == "stationary"]
        best = max(stat, key=lambda iv: iv["fastest_growth_per_s"]) if stat else None
        out["fastest"].append((best and best["fastest_lambda_cells"]) or np.nan)
        out["regime"].append(d["regime"])
    return out


def plot_phase_diagram(
    ds: xr.Dataset, base: Scene | None = None, *, ax: Axes | None = None, color_by: str | None = None
) -> FigureBase:
    """Every point of the sweep against sigma, drawn by outcome: the selected wavelength (2(N-1)/Z, cells) of a
    pattern, rest at the bottom edge, an oscillation or a still-moving run at the top edge, failures as crosses;
    with a second swept key (color_by: its coordinate name; default the first swept key besides sigma and seed)
    the points are coloured by its value. Beside them the linear theory of the base scene's model at each sigma:
    every unstable interval (stationary shaded blue, oscillatory hatched red; an interval reaching lambda -> inf
    is drawn up to the top edge) and the fastest wavelength. Returns the Figure."""
    from .plots import new_figure

    sname = _coord(ds, "params.sigma")
    if sname is None:
        raise SweepError("phase diagram: params.sigma is not swept")
    if ax is None:
        fig = new_figure(figsize=(10, 5), constrained_layout=True)
        ax = fig.add_subplot(111)
    n = int(ds.attrs.get("cells", 16))
    ylo, yhi = 1.5, 4.0 * n
    others = [str(d) for d in ds["status"].dims if d not in (sname, "seed")]
    cby = color_by if color_by is not None else (others[0] if others else None)
    if cby is not None and cby not in others:
        raise SweepError(f"phase diagram: color_by={cby!r} is not a swept key; swept: {', '.join(others) or 'none'}")
    order = [sname] + ([cby] if cby else []) + [d for d in ds["status"].dims if d not in (sname, cby)]
    sig = np.asarray(ds[sname].values, dtype=float)
    lam = ds["pattern_wavelength_cells"].transpose(*order).values
    outc = ds["outcome"].transpose(*order).values.astype(str) if "outcome" in ds else None
    cvals = list(ds[cby].values) if cby else [None]
    lam = lam.reshape(len(sig), len(cvals), -1)
    outc = outc.reshape(lam.shape) if outc is not None else np.where(np.isfinite(lam), "pattern", "moving")
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    spread = 0.004 * (sig.max() - sig.min() or 1.0)  # colours side by side, not on top of each other
    for ci in range(len(cvals)):
        dx = (ci - (len(cvals) - 1) / 2) * spread if len(cvals) > 1 else 0.0
        for oc, (mk, col, label) in OUTCOME_STYLE.items():
            m = outc[:, ci, :] == oc
            if not m.any():
                continue
            xs = np.repeat(sig, m.shape[1]).reshape(m.shape)[m] + dx
            if oc == "pattern":
                ys = lam[:, ci, :][m]
            elif oc in ("rest", "failed"):
                ys = np.full(xs.shape, ylo * 1.08)
            else:
                ys = np.full(xs.shape, yhi / 1.12)
            colour = col if cby is None or oc in ("failed",) else cmap(ci / max(1, len(cvals) - 1))
            lab = label if ci == 0 else None
            ax.plot(xs, ys, mk, ms=4, alpha=0.7, color=colour, mfc=colour if oc == "pattern" else "none", label=lab)
    if cby:
        from matplotlib.lines import Line2D

        handles = [
            Line2D(
                [],
                [],
                marker="o",
                ls="",
                color=cmap(ci / max(1, len(cvals) - 1)),
                label=f"{cby} = {cv:g}" if isinstance(cv, (float, int, np.number)) else f"{cby} = {cv}",
            )
            for ci, cv in enumerate(cvals)
        ]
        leg2 = ax.legend(
            handles=handles, fontsize=7, loc="lower left", bbox_to_anchor=(1.01, 0.0), title="colour", title_fontsize=7
        )
        ax.add_artist(leg2)
    if base is not None:
        sg = np.linspace(sig.min(), sig.max(), max(80, len(sig)))
        th = theory_bands_over(base, sg)
        for kind, colour, hatch in (("stationary", "C0", None), ("oscillatory", "C3", "//")):
            slots = max([0] + [len(x) for x in th[kind]])
            for k in range(slots):
                lo = np.array([x[k][0] if len(x) > k else np.nan for x in th[kind]])
                hi = np.array([min(x[k][1], yhi) if len(x) > k else np.nan for x in th[kind]])
                ax.fill_between(
                    sg,
                    lo,
                    hi,
                    color=colour,
                    alpha=0.15,
                    hatch=hatch,
                    lw=0,
                    label=f"linear theory: {kind} unstable" if k == 0 else None,
                )
        ax.plot(sg, th["fastest"], color="C0", lw=1.2, label="linear theory: fastest stationary wavelength")
        from ..analysis.stability import theory_of

        tname = theory_of(base.model, base.params, base.options.inertia).label()
    else:
        tname = ""
    ax.set_ylim(ylo, yhi)
    ax.set_yscale("log")
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullFormatter

    ax.yaxis.set_major_locator(FixedLocator([t for t in (2, 3, 5, 7.5, 10, 15, 20, 30, 60) if t < yhi]))
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("sigma (N·m/rad)")
    ax.set_ylabel("wavelength (cells)")
    nseed = ds.sizes.get("seed", 1)
    pooled = [d for d in ds["status"].dims if d not in (sname, cby)]
    ax.set_title(
        f"phase diagram: {ds.attrs.get('scene', '')}, {int(np.prod([ds.sizes[d] for d in pooled])) if pooled else 1} "
        f"point(s) per marker column{f' ({nseed} seeds)' if 'seed' in pooled else ''}"
        + (f"\ntheory: {tname}" if tname else ""),
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: it never hides a point
    return ax.figure


def outcome(ds: xr.Dataset) -> np.ndarray:
    """Per point: the index in OUTCOMES (rest, pattern, oscillation, moving, failed); -1 pending."""
    if "outcome" in ds:
        oc = ds["outcome"].values.astype(str)
    else:  # an older dataset
        rest = ds["at_rest"].values == 1
        osc = np.isfinite(ds["oscillation_period_s"].values)
        steady = ds["steady"].values == 1
        oc = np.where(rest, "rest", np.where(osc, "oscillation", np.where(steady, "pattern", "moving")))
        st = ds["status"].values.astype(str)
        oc = np.where(st == "failed", "failed", oc)
    code = np.full(oc.shape, -1)
    for i, name in enumerate(OUTCOMES):
        code[oc == name] = i
    code[ds["status"].values.astype(str) == "pending"] = -1
    return code


REGIME_MARKERS = {
    "rest": ".",
    "stationary_pattern": "o",
    "broadband_pattern": "s",
    "uniform_oscillation": "^",
    "pattern_and_oscillation": "D",
}


def plot_regime_map(ds: xr.Dataset, xkey: str, ykey: str, *, ax: Axes | None = None) -> FigureBase:
    """The most frequent outcome (rest / pattern / oscillation / moving / failed) over the other swept keys, on xkey
    x ykey (coordinate names, or the swept keys), and on each cell a marker for the regime the linear theory of
    the model that ran gives there (first point of the pooled ones). Returns the Figure."""
    from matplotlib.colors import ListedColormap

    from .plots import new_figure

    xkey = _coord(ds, xkey) or xkey
    ykey = _coord(ds, ykey) or ykey
    for k in (xkey, ykey):
        if k not in ds.dims:
            raise SweepError(f"regime map: {k!r} is not a swept key; swept: {', '.join(map(str, ds['status'].dims))}")
    if ax is None:
        fig = new_figure(figsize=(7.5, 4.8), constrained_layout=True)
        ax = fig.add_subplot(111)
    import xarray as xr

    dims = ds["status"].dims
    code = xr.DataArray(outcome(ds), dims=dims).transpose(ykey, xkey, ...)
    c = code.values.reshape(code.shape[0], code.shape[1], -1)
    mode = np.full(c.shape[:2], -1)
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            v = c[i, j][c[i, j] >= 0]
            if len(v):
                mode[i, j] = np.bincount(v, minlength=len(OUTCOMES)).argmax()
    colours = ["0.85", "C0", "C3", "C1", "k"]
    cmap = ListedColormap(colours)
    xv, yv = np.asarray(ds[xkey].values), np.asarray(ds[ykey].values)
    ax.imshow(
        np.ma.masked_less(mode, 0),
        origin="lower",
        aspect="auto",
        cmap=cmap,
        vmin=-0.5,
        vmax=len(OUTCOMES) - 0.5,
        interpolation="nearest",
    )
    from matplotlib.artist import Artist
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Artist] = [Patch(color=cmap(i), label=f"run: {o}") for i, o in enumerate(OUTCOMES)]
    if "regime" in ds:
        reg = ds["regime"].transpose(ykey, xkey, ...).values.astype(str).reshape(len(yv), len(xv), -1)[:, :, 0]
        for name, mk in REGIME_MARKERS.items():
            yy, xx = np.nonzero(reg == name)
            if len(xx):
                ax.plot(xx, yy, mk, ms=4, color="w", mec="k", mew=0.6, ls="")
                handles.append(Line2D([], [], marker=mk, ls="", color="w", mec="k", label=f"theory: {name}"))
    ax.set_xticks(range(len(xv)))
    ax.set_xticklabels(
        [f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v) for v in xv],
        rotation=90 if len(xv) > 8 else 0,
        fontsize=7,
    )
    ax.set_yticks(range(len(yv)))
    ax.set_yticklabels([f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v) for v in yv], fontsize=7)
    if len(xv) > 16:
        for lab in ax.get_xticklabels()[1::2]:
            lab.set_visible(False)
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel(ds[xkey].attrs.get("key", xkey))
    ax.set_ylabel(ds[ykey].attrs.get("key", ykey))
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
    ap.add_argument(
        "--accuracy",
        choices=("fast", "balanced", "exact"),
        default=None,
        help="stepper/step/model fidelity preset of every point, as `run --accuracy` (default: the scene's)",
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
    ap.add_argument("--quiet", action="store_true", help="no progress bar (it shows on a terminal only anyway)")
    args = ap.parse_args(argv)
    from ..models import ConfigError

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
            accuracy=args.accuracy,
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
