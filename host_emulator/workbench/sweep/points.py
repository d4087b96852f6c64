"""One chunk of points, the task each Dask worker runs: the points run as one batched call, each summarised into
the sweep's observables (a failing point recorded, never dropped)."""

from __future__ import annotations

from ...analysis.summary import summarize
from ...construct import scene_cost
from ..batch import run_batch
from .grid import _load_spec
from .schema import OBSERVABLES, _num, outcome_of


def evaluate_points(specs: list[dict]) -> list[dict]:
    """Run each point spec and return one result dict per spec, in order; a failing point gives
    {"status": "failed", "error": "<Type>: <message>"} instead of raising. The points of a chunk run together
    in one compiled call (host_emulator.workbench.batch.run_batch: hil lattices batched, bit-identical to run_scene;
    other models one by one), so a point costs no Python per control tick."""
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
            r["pattern_kind"] = str(s.get("pattern_kind") or "")  # a sheet's (analysis.pattern2d); "" on a chain
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
