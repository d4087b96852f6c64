"""The store: points.jsonl, one line per finished point, appended as chunks finish and read back on a re-run (the
sweep resumes)."""

from __future__ import annotations

import json
import math
from pathlib import Path


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
