"""summary.json says what ran: every option an accuracy preset changes appears in model_options with the value the
run used (the solver's own report and the trajectories agree), and summary["accuracy"] lists them."""

import dataclasses
import json

import numpy as np
import pytest

from host_emulator.accuracy import KNOB_KEYS, LEVELS
from host_emulator.analysis.summary import summarize
from host_emulator.cli import main
from host_emulator.controller import RunResult, run_scene
from host_emulator.scene import load_scene


@pytest.mark.parametrize("model", ["lattice", "hil"])
@pytest.mark.parametrize("level", LEVELS)
def test_every_option_a_preset_changes_is_recorded_as_it_ran(model, level, tmp_path):
    out = tmp_path / "o"
    argv = ["run", "default", "--set", f"model={model}", "--set", "t_end_s=0.05", "--accuracy", level]
    assert main([*argv, "--quiet", "--no-plots", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    mo, info, acc = s["model_options"], s["solver"], s["accuracy"]
    # the solver's own report of its step
    assert mo["stepper"] == info["stepper"]
    if model == "hil":
        assert mo["substeps"] == info["substeps_per_tick"]
    elif mo["stepper"] == "dop853":
        assert mo["tol"] == info["tol"]
    else:  # dt caps the step: the solver takes the largest step <= dt that divides the output interval
        assert info["dt_s"] == pytest.approx(mo["dt_out"] / np.ceil(mo["dt_out"] / mo["dt"] - 1e-9), rel=1e-12)
    # the presets as documented (docs/accuracy.md): exact turns the geometric beta form on where the scene leaves it
    assert mo["beta_geometry"] == ("geometric" if level == "exact" else "small")
    # every knob that differs from the scene's own value is listed with the value it ran with, and nothing else
    scene_opts = dataclasses.asdict(load_scene("default", [f"model={model}"]).options)
    changed = {k: mo[k] for k in KNOB_KEYS if mo[k] != scene_opts[k]}
    assert acc["preset_changed"] == changed and acc["level"] == level and acc["scene_set"] == []
    assert {k: v for k, v in mo.items() if k not in KNOB_KEYS} == {
        k: v for k, v in scene_opts.items() if k not in KNOB_KEYS
    }


@pytest.mark.parametrize(
    ("model", "spelled_out"),
    [
        ("lattice", ['model_options.stepper="dop853"', "model_options.tol=1e-8"]),
        ("hil", ['model_options.stepper="rk4"', "model_options.substeps=2"]),
    ],
)
def test_the_recorded_beta_geometry_is_the_one_that_ran(model, spelled_out):
    """accuracy exact on the default scene runs exactly what summary.json records: the same run with those options
    set by hand is bit-identical, and with the small-angle beta it is not."""
    base = [f"model={model}", "t_end_s=0.5"]
    sc = load_scene("default", [*base, "accuracy=exact"])
    res = run_scene(sc, progress=False)
    mo = summarize(sc, res)["model_options"]
    hand = {
        g: run_scene(load_scene("default", [*base, *spelled_out, f'model_options.beta_geometry="{g}"']), progress=False)
        for g in ("geometric", "small")
    }
    assert mo["beta_geometry"] == "geometric"
    assert np.array_equal(res.alpha, hand["geometric"].alpha) and np.array_equal(res.beta, hand["geometric"].beta)
    assert not np.array_equal(res.alpha, hand["small"].alpha)


def test_without_the_solver_options_the_summary_resolves_the_preset():
    """A RunResult that carries no options (built by hand, or by older code) still gets the options the preset
    gives; a summary of rig data keeps the scene's options and has no accuracy record."""
    sc = load_scene("default", ["model=lattice", "accuracy=exact", "t_end_s=0.2"])
    res = run_scene(sc, progress=False)
    bare = RunResult(res.t, res.alpha, res.beta, res.wall_s, res.info)
    a, b = summarize(sc, res), summarize(sc, bare)
    assert a["model_options"] == b["model_options"] and a["accuracy"] == b["accuracy"]
    rig = summarize(sc, bare, source="rig")
    assert "accuracy" not in rig and rig["model_options"]["beta_geometry"] == "small"


def test_batched_runs_carry_their_options():
    from host_emulator.workbench.batch import run_batch

    scenes = [load_scene("default", ["t_end_s=0.2", "accuracy=exact"]), load_scene("default", ["t_end_s=0.2"])]
    for sc, r in zip(scenes, run_batch(scenes)):
        assert r.options == run_scene(sc, progress=False).options
    assert run_batch(scenes)[0].options.beta_geometry == "geometric"
