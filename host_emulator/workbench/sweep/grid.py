"""The grid: ``KEY=START:STOP:NUM`` or ``KEY=V1,V2,...`` parsed, every grid point (x seeds) as a spec of scene
overrides, and a spec's scene loaded."""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence

from ...scene import _value, apply_overrides, load_scene, scene_from_dict
from .errors import SweepError

MAX_POINTS = 1_000_000  # grid points x seeds: the point list, the store and the dataset stay within memory


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
    if isinstance(spec["scene"], dict):
        return scene_from_dict(apply_overrides(spec["scene"], spec["overrides"]), "")
    return load_scene(spec["scene"], spec["overrides"])
