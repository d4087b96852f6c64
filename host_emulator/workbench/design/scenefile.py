"""What a design writes of its parameters: the scene.toml that `run` and the rig load, and the parameters as
design.json lists them."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ...params import REACTION_KEYS, Params
from .constants import NOMINAL_PUSH
from .ensembles import _scene_table
from .target import Target


def _write_scene(path: Path, base_table: dict, p: Params, pushes, target: Target, name: str) -> None:
    import tomli_w

    t = _scene_table(base_table, p, pushes, *NOMINAL_PUSH)
    defaults = dataclasses.asdict(Params(cells=p.cells))
    t["params"] = {
        k: v for k, v in t["params"].items() if k in REACTION_KEYS or k in FIRMWARE_KEYS or v != defaults.get(k)
    }
    for k in FIRMWARE_KEYS:  # what the search held fixed, written even where it is the default (design.json: assumes)
        t["params"][k] = getattr(p, k)
    t.setdefault("model_options", {})["stepper"] = assumed_options(base_table, p)["stepper"]
    t["accuracy"] = base_table.get("accuracy", "balanced")
    t["name"] = name
    t["description"] = (
        f"designed for {target.text()} with push(es) on "
        + ", ".join(f"alpha_{q.cell} ({'CCW' if q.sign > 0 else 'CW'})" for q in pushes)
        + " (python -m host_emulator design, docs/design.md)"
    )
    t["model"] = "hil"
    t.get("model_options", {}).pop("noise", None)
    head = (
        f"# Scene written by `python -m host_emulator design` (docs/design.md): target {target.text()}.\n"
        f"# Run it: python -m host_emulator run {path}\n"
        f"# On the rig: python -m metacell_tools.experiment run {path} -c PORT@115200 (or `rehearse`)\n"
    )
    path.write_text(head + tomli_w.dumps(t))


# the firmware settings a design holds fixed (the cells' configuration on the rig): scene.toml writes every one
FIRMWARE_KEYS = ("bemf_comp", "pwm_top", "vmax_v", "supply_v", "control_rate_hz")


def pwm_limit_ticks(p: Params) -> int:
    """The PWM limit in force in a cell configured for these parameters: the runner's PWM_LIMIT command
    (image.model.setup_commands) clamped by the firmware to duty_max = floor(vmax_mv * pwm_top / supply_mv)."""
    sent = round(min(p.vmax_v, p.supply_v) / p.supply_v * p.pwm_top)
    return min(sent, round(p.vmax_v * 1000) * p.pwm_top // round(p.supply_v * 1000))


def assumed_options(base_table: dict, p: Params) -> dict:
    """The hil model options the search ran with (its accuracy preset resolved): stepper, plant steps per tick."""
    from ...accuracy import resolve_options
    from ...scene import scene_from_dict

    sc = scene_from_dict(base_table)
    o = resolve_options("hil", p, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    return {
        "stepper": o.stepper,
        "substeps": o.substeps,
        "accuracy": sc.accuracy,
        "inertia": o.inertia,
        "bands": o.bands,
        "beta_geometry": o.beta_geometry,
        "perturb_via": o.perturb_via,
    }


def assumes_doc(base_table: dict, p: Params) -> dict:
    """design.json's `assumes`: every firmware setting and model option the search held fixed."""
    fw = {k: getattr(p, k) for k in FIRMWARE_KEYS}
    fw["pwm_limit_ticks"] = pwm_limit_ticks(p)
    return {
        "model": "hil",
        "firmware": fw,
        "model_options": assumed_options(base_table, p),
        "rig": "`command apply` reads every cell's back-EMF compensation and PWM limit and refuses a design whose "
        "values differ (--configure sets them); control_rate_hz and pwm_top are the build's (platformio.ini), "
        "not readable over the bus",
    }


def _params_doc(p: Params) -> dict:
    return {k: (list(getattr(p, k)) if isinstance(getattr(p, k), tuple) else getattr(p, k)) for k in REACTION_KEYS}
