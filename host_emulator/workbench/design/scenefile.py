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
    t["params"] = {k: v for k, v in t["params"].items() if k in REACTION_KEYS or v != defaults.get(k)}
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


def _params_doc(p: Params) -> dict:
    return {k: (list(getattr(p, k)) if isinstance(getattr(p, k), tuple) else getattr(p, k)) for k in REACTION_KEYS}
