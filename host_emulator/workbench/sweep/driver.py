"""``sweep(...)``: the definition checked and its cost estimated before any cluster starts, the points not yet
done run on Dask, then sweep.nc and the figures."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from metacell_common.outpaths import check_out_dir

from ...construct import scene_cost
from ...limits import RunTooLarge, batch_budget
from ...scene import _value, scene_table
from ..api import override_list
from .cluster import _run_on_dask, check_scheduler
from .dataset import to_dataset
from .errors import SweepError
from .figures import _save, plot_phase_diagram, plot_regime_map
from .grid import MAX_POINTS, _load_spec, point_specs
from .kinds import plot_pattern_kinds
from .schema import coord_names
from .store import load_done

if TYPE_CHECKING:
    import xarray as xr

    from ...scene import Scene
    from ..api import Overrides


COST_SAMPLE = 8  # points whose solver is built to estimate the sweep's cost before any cluster starts


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
    """Run the sweep (see the package docstring) and return its xarray Dataset (also written to out/sweep.nc).

    scene and fixed take what host_emulator.run takes (a shipped name, a .toml path or a Scene; overrides as
    {"params.sigma": "6/125"} or ["KEY=VALUE", ...]); grid: {key: values} (a list, a range, a numpy array);
    progress: a bar on stderr (shown on a terminal only)."""
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
    cost = estimate_cost(specs)  # a bad key, a point too long or a sweep too large fails here, before any cluster
    if scheduler:
        scheduler = check_scheduler(scheduler)  # not Dask, not an address: before --out is created
    out = Path(out)
    problem = check_out_dir(out)
    if problem:
        raise SweepError(problem)
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
        # the swept keys, never the seeds (they are pooled: the map shows the most frequent outcome over them)
        keys = list(map_keys or [k for k in axes if len(axes[k]) > 1 and k != "seed"][:2])
        names = coord_names(axes)
        if len(keys) == 2:
            _save(plot_regime_map(ds, names.get(keys[0], keys[0]), names.get(keys[1], keys[1])), out / "regime_map.png")
        elif len(keys) == 1:
            _save(plot_regime_map(ds, names.get(keys[0], keys[0])), out / "regime_map.png")
        if base.params.topology.is_sheet and keys:  # a sheet: the phase diagram of its pattern kinds
            ky = names.get(keys[1], keys[1]) if len(keys) == 2 else None
            _save(plot_pattern_kinds(ds, names.get(keys[0], keys[0]), ky, base), out / "pattern_kinds.png")
    return ds


def estimate_cost(specs: list[dict]) -> float:
    """The sweep's cell steps, from COST_SAMPLE points spread over the grid (first and last included), each built
    as its run would be (construct.scene_cost: every preset and automatic step resolved). Raises RunTooLarge for a
    sampled point that is too long on its own or a sweep over the batch limit (the figure in the message)."""
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
