"""The accuracy knob: scene key and run --accuracy select stepper/step/fidelity; explicit options win; bad values
are refused naming the key; the presets order by accuracy on the lattice scene (against a tight reference)."""

import numpy as np
import pytest

from host_emulator.accuracy import resolve_options
from host_emulator.models import ConfigError, make_model
from host_emulator.scene import load_scene


def test_default_is_balanced_and_presets_apply():
    sc = load_scene("exp3_single_sigma9", ["t_end_s=1"])
    assert sc.accuracy == "balanced"
    from dataclasses import replace

    for level, frac in (("fast", 0.8), ("balanced", 0.25)):
        o = resolve_options("lattice", sc.params, sc.perturbations, sc.options, level)
        lim = make_model("lattice", sc.params, sc.perturbations, replace(o, dt=None)).step_limit()[0]
        assert o.stepper == "rk4" and o.dt == pytest.approx(frac * lim) and o.tol is None
    o = resolve_options("lattice", sc.params, sc.perturbations, sc.options, "exact")
    assert (o.stepper, o.tol, o.dt, o.beta_geometry) == ("dop853", 1e-8, None, "geometric")


def test_exact_with_a_fixed_stepper_gets_the_fine_step_and_an_adaptive_one_keeps_its_tol():
    from dataclasses import replace

    sc = load_scene("exp3_single_sigma9", ['model_options.stepper="rk4"', "accuracy=exact"])
    o = resolve_options(sc.model, sc.params, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    lim = make_model("lattice", sc.params, sc.perturbations, replace(o, dt=None)).step_limit()[0]
    assert o.stepper == "rk4" and o.dt == pytest.approx(lim / 32) and o.tol is None
    sc = load_scene("exp3_single_sigma9", ['model_options.stepper="dop853"', "model_options.tol=1e-5"])
    o = resolve_options(sc.model, sc.params, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    assert (o.stepper, o.tol, o.dt) == ("dop853", 1e-5, None)
    sc = load_scene("exp3_single_sigma9", ['model_options.stepper="dop853"'])  # balanced: no preset tol
    o = resolve_options(sc.model, sc.params, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    from host_emulator.models.options import DEFAULT_TOL

    assert o.tol == DEFAULT_TOL


def test_explicit_options_win_and_bad_level_is_refused():
    sc = load_scene("exp3_single_sigma9", ['model_options.stepper="noh_bathe"', "accuracy=exact"])
    o = resolve_options(sc.model, sc.params, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    assert o.stepper == "noh_bathe" and o.beta_geometry == "small"  # the scene file sets beta_geometry
    with pytest.raises(ConfigError, match="accuracy = 'precise'"):
        load_scene("default", ["accuracy=precise"])


def test_hil_slow_control_rate_gets_enough_substeps():
    sc = load_scene("default", ["params.control_rate_hz=100", "accuracy=fast"])
    o = resolve_options(sc.model, sc.params, sc.perturbations, sc.options, sc.accuracy, sc.explicit_options)
    m = make_model("hil", sc.params, sc.perturbations, o)
    assert o.substeps >= 2 and 0.01 / o.substeps <= m.step_limit()[0]


def test_presets_are_ordered_by_error_on_the_lattice_scene():
    """fast > balanced > exact in max angle error over 1 s of exp. 3 against the exact preset's stepper at a 1000x
    tighter tolerance."""
    from dataclasses import replace

    from host_emulator.controller import run_solver

    sc = load_scene("exp3_single_sigma9", ["t_end_s=1", 'model_options.beta_geometry="small"'])
    errs = {}
    ref_opts = replace(
        resolve_options("lattice", sc.params, sc.perturbations, sc.options, "exact", sc.explicit_options)
    )
    ref_opts = replace(ref_opts, tol=ref_opts.tol / 1000)
    ref = run_solver(make_model("lattice", sc.params, sc.perturbations, ref_opts).solver(), 1.0)
    for level in ("fast", "balanced", "exact"):
        o = resolve_options("lattice", sc.params, sc.perturbations, sc.options, level, sc.explicit_options)
        r = run_solver(make_model("lattice", sc.params, sc.perturbations, o).solver(), 1.0)
        errs[level] = np.abs(r.alpha - ref.alpha).max()
    assert errs["fast"] > errs["balanced"] > errs["exact"]
    assert errs["balanced"] < 1e-3


def test_run_accuracy_flag(tmp_path, capsys):
    from host_emulator.cli import main

    assert (
        main(
            [
                "run",
                "exp5_rest",
                "--accuracy",
                "fast",
                "--quiet",
                "--no-plots",
                "--out",
                str(tmp_path),
                "--set",
                "t_end_s=0.2",
            ]
        )
        == 0
    )
    import json

    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["solver"]["stepper"] == "symplectic_euler"  # hil fast preset
