"""Model only what the scene asks for: `question` and `model = "auto"` / `run --model auto` pick the cheapest tier
that models the question and say why in one line; `run` prints an error estimate for the accuracy it used."""

import json

import pytest

from host_emulator.cli import main
from host_emulator.models import ConfigError
from host_emulator.scene import list_scenes, load_scene, scene_from_dict, scene_table
from host_emulator.tiers import COST_MS_PER_SIM_S, QUESTIONS, fmt_cost, pick

# what each shipped scene is for, and the tier that models it at the least cost (docs/accuracy.md#tiers): the
# pattern and the long waves' oscillation need the motors' back-EMF damping and the quantised loop (hil, which
# costs less than the image), the PDE only the continuum has
EXPECTED = {
    "default": ("pattern", "hil"),
    "exp1_ccw_ccw": ("pattern", "hil"),
    "exp2_ccw_cw": ("pattern", "hil"),
    "exp3_single_sigma9": ("pattern", "hil"),
    "exp3_single_sigma6": ("pattern", "hil"),
    "exp3_single_sigma14": ("oscillation", "hil"),
    "exp4_stable_eta10": ("oscillation", "hil"),
    "exp5_rest": ("oscillation", "hil"),
    "continuum_single": ("continuum", "continuum"),
    # the sheets: the pattern a push grows into (sheet_4x4_rig: the rig re-banded as a 4 x 4 sheet)
    "sheet_4x4_rig": ("pattern", "hil"),
    "sheet_8x8": ("pattern", "hil"),
    "sheet_16x16": ("pattern", "hil"),
    "sheet_32x32": ("pattern", "hil"),
    "sheet_128x128": ("pattern", "hil"),
    "sheet_256x256": ("pattern", "hil"),
}
RUN_AUTO_MAX_CELLS = 256  # the run below (0.05 s) skips the large sheets: the suite stays fast


def test_every_shipped_scene_states_its_question():
    assert sorted(EXPECTED) == sorted(n for n, _, _ in list_scenes())
    for name, (q, _) in EXPECTED.items():
        assert load_scene(name).question == q, name


@pytest.mark.parametrize("name", sorted(n for n in EXPECTED if load_scene(n).cells <= RUN_AUTO_MAX_CELLS))
def test_run_model_auto_picks_a_tier_and_says_why(name, tmp_path, capsys):
    q, tier = EXPECTED[name]
    out = tmp_path / "o"
    rc = main(["run", name, "--model", "auto", "--set", "t_end_s=0.05", "--quiet", "--no-plots", "--out", str(out)])
    assert rc == 0
    printed = capsys.readouterr().out.splitlines()
    why = printed[0]
    assert why.startswith(f"model auto -> {tier} for question {q!r}: "), why
    assert "docs/accuracy.md#tiers" in why and len(why.split(": ", 1)[1]) > 40
    assert printed[1].startswith(f"scene {name} ({tier}): ")
    s = json.loads((out / "summary.json").read_text())
    assert s["model"] == tier
    assert s["model_choice"] == {"question": q, "reason": why}


def test_pick_is_the_cheapest_tier_that_models_the_question():
    for q, (_what, tiers, _why) in QUESTIONS.items():
        tier, why = pick(q)
        assert tier in tiers and all(COST_MS_PER_SIM_S[tier] <= COST_MS_PER_SIM_S[t] for t in tiers), q
        assert f"{fmt_cost(COST_MS_PER_SIM_S[tier])} ms" in why
    # the measured costs: the hil (the firmware in the loop) is cheaper than the image that runs its flashed code
    assert COST_MS_PER_SIM_S["hil"] < COST_MS_PER_SIM_S["image"]


def test_a_scene_with_faults_and_no_question_goes_to_the_image():
    d = {
        "name": "f",
        "model": "auto",
        "cells": 4,
        "t_end_s": 0.1,
        "fault": [{"kind": "hardfault", "start_s": 0.05, "cell": 2}],
    }
    sc = scene_from_dict(d)
    assert (sc.model, sc.question) == ("image", "faults")
    assert sc.model_reason.startswith("model auto -> image for question 'faults': ")
    assert scene_table(sc)["question"] == "faults" and scene_table(sc)["model"] == "image"


def test_model_auto_without_a_question_or_with_a_bad_one_is_refused(tmp_path, capsys):
    with pytest.raises(ConfigError, match="states no question; set question = one of pattern"):
        scene_from_dict({"name": "x", "model": "auto", "cells": 4, "t_end_s": 0.1})
    with pytest.raises(ConfigError, match=r"question = 'bus ' \(did you mean 'bus'\?\): expected one of"):
        scene_from_dict({"name": "x", "model": "lattice", "cells": 4, "t_end_s": 0.1, "question": "bus "})
    f = tmp_path / "s.toml"
    f.write_text('name = "s"\nmodel = "lattice"\ncells = 4\nt_end_s = 0.1\n')
    out = tmp_path / "o"
    assert main(["run", str(f), "--model", "auto", "--quiet", "--no-plots", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "states no question" in err
    assert not out.exists()


def test_run_prints_the_error_estimate_of_its_accuracy(tmp_path, capsys):
    """The line quotes the preset's measured integration error and the tier's difference from the next tier up,
    the same figures summary.json records; a scene that sets a knob itself gets no preset figure."""
    from host_emulator.tiers import ERROR_VS_UP_RAD, PRESET_ERROR_RAD

    for level in ("fast", "balanced", "exact"):
        out = tmp_path / level
        argv = ["run", "default", "--set", "model=lattice", "--set", "t_end_s=0.05", "--accuracy", level]
        assert main([*argv, "--quiet", "--no-plots", "--out", str(out)]) == 0
        line = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("  accuracy ")]
        est = json.loads((out / "summary.json").read_text())["accuracy"]["error_estimate"]
        assert est["integration_rad"] == PRESET_ERROR_RAD["lattice", level]
        assert est["vs_next_tier_rad"] == ERROR_VS_UP_RAD["lattice"] and est["next_tier"] == "hil"
        assert line == [
            f"  accuracy {level}: error estimate (max angle, measured on the default scene over 3 s): integration "
            f"~{est['integration_rad']:.2g} rad against a converged step; ~{est['vs_next_tier_rad']:.2g} rad from "
            "the hil tier"
        ]
    out = tmp_path / "own"
    argv = ["run", "default", "--set", "model_options.stepper=euler", "--set", "t_end_s=0.05"]
    assert main([*argv, "--quiet", "--no-plots", "--out", str(out)]) == 0
    assert "the scene sets stepper itself: no preset figure" in capsys.readouterr().out
    assert json.loads((out / "summary.json").read_text())["accuracy"]["error_estimate"]["integration_rad"] is None
