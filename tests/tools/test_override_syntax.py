"""One override syntax everywhere: a fraction such as 9/125 means the same number on the command line (`run --set`,
`dispersion --set`, `sweep --grid`, the rig's `command set`), in the Python API's dict overrides and sweep grids;
a bare key gets a did-you-mean hint."""

import argparse

import pytest

import host_emulator as he
from host_emulator.analysis.cli import parse_set
from host_emulator.models import ConfigError
from host_emulator.params import Params
from host_emulator.scene import load_scene
from host_emulator.workbench.sweep import parse_grid
from metacell_tools.rigtools import command


def test_a_fraction_is_the_same_number_everywhere():
    want = 9 / 125
    assert load_scene("default", ["params.sigma=9/125"]).params.sigma == want
    assert he.load_scene("default", {"params.sigma": "9/125"}).params.sigma == want
    assert he.load_scene("default", ["params.sigma=9/125"]).params.sigma == want
    assert parse_set(Params(), ["sigma=9/125"]).sigma == want
    assert parse_grid("params.sigma=9/125,6/125")[1] == [want, 6 / 125]
    args = command.parser().parse_args(["-c", "-", "set", "8", "sigma", "9/125"])
    assert args.value == want
    reg, values = command.build(args)
    assert (
        reg == "SIGMA"
        and values == command.build(command.parser().parse_args(["-c", "-", "set", "8", "sigma", "0.072"]))[1]
    )
    with pytest.raises(SystemExit):
        command.parser().parse_args(["-c", "-", "set", "8", "sigma", "9/0"])
    with pytest.raises(argparse.ArgumentTypeError):
        command.number("1/0")


def test_dict_overrides_keep_words_booleans_and_numbers():
    sc = he.load_scene(
        "exp1_ccw_ccw",
        {"model_options.perturb_via": "firmware", "params.bemf_comp": True, "t_end_s": 2, "params.eta_scale": 1.5},
    )
    assert sc.options.perturb_via == "firmware" and sc.params.bemf_comp is True
    assert sc.t_end_s == 2.0 and sc.params.eta_scale == 1.5


def test_overrides_apply_to_a_scene_object_as_it_is():
    """A Scene changed in Python (dataclasses.replace) keeps its changes when overrides are applied on top."""
    import dataclasses

    sc = dataclasses.replace(load_scene("default"), t_end_s=3.0)
    out = he.load_scene(sc, {"params.sigma": "6/125"})
    assert out.t_end_s == 3.0 and out.params.sigma == 6 / 125 and out.model == sc.model


@pytest.mark.parametrize("key,hint", [("sigma", "params.sigma"), ("torque_Nm", "perturbation.N.torque_Nm")])
def test_bare_keys_get_a_hint(key, hint):
    with pytest.raises(ConfigError, match=f"did you mean {hint}"):
        he.load_scene("default", {key: 0.05})
    with pytest.raises(ConfigError, match=f"did you mean {hint}"):
        load_scene("default", [f"{key}=0.05"])


def test_run_result_has_one_name_for_its_times():
    r = he.run("default", {"t_end_s": 0.1})
    assert r.time.shape == (11,)
    with pytest.raises(AttributeError, match="r.time"):
        r.t  # noqa: B018 - the attribute access is the test
