"""Batched hil ensembles: a candidate's scene tables (its pushes, the noise model) and the runner that runs them,
in this process or chunked over a Dask cluster (run_tables is the task sent to the workers)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

from ...analysis.observables import is_steady
from ...params import REACTION_KEYS, Params
from ...scene import scene_from_dict
from ..batch import run_batch
from .constants import NOISE
from .target import Push


def _scene_table(base_table: dict, p: Params, pushes: Sequence[Push], torque: float, duration: float) -> dict:
    t = json.loads(json.dumps(base_table))
    for k in REACTION_KEYS:
        v = getattr(p, k)
        t["params"][k] = list(v) if isinstance(v, tuple) else v
    t["perturbation"] = [
        {"cell": q.cell, "chain": "alpha", "torque_Nm": q.sign * torque, "start_s": 0.1, "duration_s": duration}
        for q in pushes
    ]
    return t


def noise_overrides(seed: int) -> list[str]:
    """The --set items of the noise model with this seed (what a verification run uses)."""
    return [f"model_options.noise.seed={seed}"] + [f"model_options.noise.{k}={v}" for k, v in NOISE.items()]


def _noise(t: dict, seed: int | None) -> dict:
    t = json.loads(json.dumps(t))
    nz = t.setdefault("model_options", {}).setdefault("noise", {})
    if seed is None:
        for k, v in NOISE.items():
            if not isinstance(v, str):
                nz[k] = 0.0
    else:
        nz.update(NOISE)
        nz["seed"] = seed
    return t


def run_tables(tables: list[dict]) -> list[dict]:
    """Run scene tables as one batched hil ensemble (workbench.batch); per run {final_alpha, final_beta, steady}
    or {error}. The Dask task of a design's search."""
    scenes = [scene_from_dict(t) for t in tables]
    out: list[dict[str, Any]] = []
    for r in run_batch(scenes, errors="return"):
        if isinstance(r, BaseException):
            out.append({"error": f"{type(r).__name__}: {r}"})
            continue
        out.append(
            {
                "final_alpha": r.alpha[-1].tolist(),
                "final_beta": r.beta[-1].tolist(),
                "steady": is_steady(r.t, r.alpha, r.beta),
            }
        )
    return out


class Runner:
    """Runs lists of scene tables: in this process, or chunked over a Dask cluster (--scheduler)."""

    def __init__(self, scheduler: str | None = None) -> None:
        self.client = None
        self.runs = 0
        if scheduler:
            from distributed import Client

            self.client = Client(scheduler, timeout="20s")

    def __call__(self, tables: list[dict]) -> list[dict]:
        self.runs += len(tables)
        if self.client is None:
            return run_tables(tables)
        nw = max(1, len(self.client.scheduler_info().get("workers", {})))
        size = max(1, math.ceil(len(tables) / (2 * nw)))
        chunks = [tables[i : i + size] for i in range(0, len(tables), size)]
        futs = self.client.map(run_tables, chunks, pure=False, retries=2)
        try:
            return [r for part in self.client.gather(futs) for r in part]
        except KeyboardInterrupt:
            from ..sweep.cluster import quiet_shutdown

            quiet_shutdown()  # Ctrl-C: one line (the caller's), no traceback of the client's cancelled tasks
            raise

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
