"""Step 3, verification: the written scene.toml run as `run` loads it, over draws of the rig's uncertainty and the
push range; and the same draws in a second model (the cross-model check)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ...physics import reaction
from ...scene import load_scene, scene_table
from .constants import CROSS_MODEL, NOISE, PUSH_DURATIONS_S, PUSH_TORQUES_NM, VERIFY_SEED0
from .ensembles import Runner, _noise
from .landing import final_walls, miss_reason, torque_ok
from .target import Target


def cross_table(table: dict, model: str = CROSS_MODEL) -> dict:
    """A hil scene table as the second model runs it: the same scene and noise draws, the model's own accuracy
    preset (the hil's stepper and plant steps are the firmware loop's, not the lattice's)."""
    t = json.loads(json.dumps(table))
    t["model"] = model
    mo = t.get("model_options", {})
    for k in ("stepper", "substeps", "dt", "perturb_via"):
        mo.pop(k, None)
    return t


def verify(
    scene_path: Path,
    target: Target,
    runner: Runner,
    seeds: int = 20,
    *,
    pushes_too: bool = True,
    model: str | None = None,
    overrides: Sequence[str] = (),
    seed0: int = VERIFY_SEED0,
) -> dict:
    """Run the written scene file as `run` loads it: `seeds` noise seeds (VERIFY_SEED0..: draws of the rig's
    uncertainty) and, with pushes_too, every push of the documented range (no noise); the fraction of each that
    lands, and every run's walls. model: run it in that model instead (cross_table: the same draws); overrides:
    --set items applied to the scene first (e.g. another firmware setting than the design assumes); seed0: the first
    seed (another range: fresh draws)."""
    sc = load_scene(str(scene_path), list(overrides))
    p = sc.params
    base = scene_table(sc)
    if model is not None:
        base = cross_table(base, model)
    tables = [_noise(base, seed0 + s) for s in range(seeds)]
    grid = [(tq, du) for tq in PUSH_TORQUES_NM for du in PUSH_DURATIONS_S] if pushes_too else []
    for tq, du in grid:
        t = _noise(base, None)
        for q in t["perturbation"]:
            q["torque_Nm"] = math.copysign(tq, q["torque_Nm"])
            q["duration_s"] = du
        tables.append(t)
    res = runner(tables)
    cap = p.kt * p.vmax_v
    runs = []
    for i, r in enumerate(res):
        what = {"seed": seed0 + i} if i < seeds else {"torque_Nm": grid[i - seeds][0], "duration_s": grid[i - seeds][1]}
        if "error" in r:
            runs.append({**what, "landed": False, "error": r["error"]})
            continue
        a, b = np.asarray(r["final_alpha"]), np.asarray(r["final_beta"])
        ra, rb = reaction(p, a, b)
        why = miss_reason(target, a, bool(r["steady"]), torque_ok(p, a, b))
        runs.append(
            {
                **what,
                "landed": why is None,
                "why": why,
                "walls": final_walls(a, target.rest),
                "steady": bool(r["steady"]),
                "torque_fraction": float(max(np.abs(ra).max(), np.abs(rb).max()) / cap),
                "final_alpha_rad": [round(float(v), 4) for v in a],
            }
        )
    fs = float(np.mean([r["landed"] for r in runs[:seeds]])) if seeds else None
    fp = float(np.mean([r["landed"] for r in runs[seeds:]])) if grid else None
    return {
        "model": base["model"],
        "seeds": seeds,
        "noise": NOISE,
        "fraction_seeds": fs,
        "push_torques_Nm": list(PUSH_TORQUES_NM) if grid else [],
        "push_durations_s": list(PUSH_DURATIONS_S) if grid else [],
        "fraction_pushes": fp,
        "max_torque_fraction": max((r.get("torque_fraction", 0.0) for r in runs), default=0.0),
        "runs": runs,
    }
