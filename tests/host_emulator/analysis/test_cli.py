"""`dispersion` command: JSON contract, overrides, human table, clean errors."""

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis.cli import dispersion_main, parse_set
from host_emulator.analysis.stability import Theory, dispersion
from host_emulator.params import Params


def run(capsys, *argv):
    rc = dispersion_main(list(argv))
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_json_contract_and_values(capsys):
    rc, out, _ = run(capsys, "--sigma", "9/125", "--json")
    assert rc == 0
    d = json.loads(out)
    for k in (
        "regime",
        "theory",
        "fastest_lambda_cells",
        "fastest_growth_per_s",
        "oscillation_period_s",
        "unstable_set_cells",
        "unstable_intervals",
    ):
        assert k in d
    ref = dispersion(Params(sigma=9 / 125), inertia=True)  # the default theory: the lattice with inertia
    assert d["regime"] == "stationary_pattern" and d["inertia"] is True and d["theory"] == "lattice with inertia"
    assert d["fastest_lambda_cells"] == pytest.approx(ref["fastest_lambda_cells"])
    assert d["unstable_set_cells"] == [pytest.approx(iv) for iv in ref["unstable_set_cells"]]


def test_acceptance_twelve_over_125_reports_both_intervals(capsys):
    rc, out, _ = run(capsys, "--sigma", "12/125", "--inertia", "--band-scale", "0.5", "--json")
    d = json.loads(out)
    assert rc == 0 and d["regime"] == "pattern_and_oscillation"
    assert [[round(x, 2) if x else x for x in iv] for iv in d["unstable_set_cells"]] == [[4.51, 7.54], [19.27, None]]


def test_models_name_their_theory(capsys):
    """--model hil adds the motors' back-EMF damping (14/125: rest, as the shipped hil scene), --no-inertia is
    the source's overdamped theory, --model continuum has no inertia."""
    rc, out, _ = run(capsys, "--sigma", "14/125", "--model", "hil", "--json")
    d = json.loads(out)
    assert d["regime"] == "rest" and d["motor_damping_Nms"] > 0 and d["theory"].startswith("hil:")
    rc, out, _ = run(capsys, "--sigma", "14/125", "--model", "hil", "--set", "bemf_comp=true", "--json")
    assert json.loads(out)["regime"] == "uniform_oscillation"
    rc, out, _ = run(capsys, "--sigma", "14/125", "--no-inertia", "--json")
    assert json.loads(out)["regime"] == "rest"
    rc, out, _ = run(capsys, "--sigma", "9/125", "--model", "continuum", "--json")
    d = json.loads(out)
    assert d["model"] == "continuum" and d["inertia"] is False


def test_flags_reach_the_analysis(capsys):
    rc, out, _ = run(
        capsys,
        "--sigma",
        "0.112",
        "--inertia",
        "--eta-scale",
        "10",
        "--continuum",
        "--set",
        "gamma=0.1",
        "--cells",
        "16",
        "--json",
    )
    d = json.loads(out)
    ref = dispersion(Params(sigma=0.112, eta_scale=10.0), inertia=True, discrete=False, n_cells=16)
    assert rc == 0 and d["model"] == "continuum" and d["inertia"] is True and d["regime"] == "rest"
    assert d["fastest_growth_per_s"] == pytest.approx(ref["fastest_growth_per_s"])
    assert len(d["lattice_modes"]) == 16
    rc, out, _ = run(capsys, "--sigma", "0.112", "--inertia", "--json")
    assert json.loads(out)["regime"] == "uniform_oscillation"


def test_human_table(capsys):
    rc, out, _ = run(capsys, "--sigma", "6/125")
    assert rc == 0 and "broadband_pattern" in out and "inf)" in out and "linear theory: lattice with inertia" in out


@pytest.mark.parametrize(
    "argv,msg",
    [
        (["--sigma", "abc"], "not a number"),
        (["--set", "nope=1"], "unknown parameter"),
        (["--set", "eta_a=-1"], "eta_alpha"),
        (["--set", "k_ab"], "KEY=VALUE"),
        (["--eta-scale", "inf"], "finite"),
    ],
)
def test_errors_are_clean(capsys, argv, msg):
    rc, out, err = run(capsys, *argv)
    assert rc == 2 and out == "" and msg in err


def test_parse_set_types():
    p = parse_set(Params(), ["params.sigma=6/125", "cells=8", "bemf_comp=false"])
    assert p.sigma == pytest.approx(0.048) and p.cells == 8 and p.bemf_comp is False


@settings(max_examples=100, deadline=None)
@given(st.integers(-(10**6), 10**6), st.integers(1, 10**6))
def test_fraction_parser(num, den):
    p = parse_set(Params(), [f"sigma={num}/{den}"])
    assert p.sigma == num / den


@settings(max_examples=100, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_float_parser_round_trips(x):
    assert parse_set(Params(), [f"sigma={x!r}"]).sigma == x


def test_sheet_prints_its_annulus_and_fastest_mode(capsys):
    """--sheet ROWSxCOLS adds the 2-D theory (analysis.sheet): the acceptance case, a 16 x 16 periodic sheet at
    9/125, grows a wavelength inside the annulus within 25 % of the fastest one."""
    from host_emulator.analysis import sheet

    rc, out, _ = run(capsys, "--sigma", "9/125", "--sheet", "16x16", "--boundary", "periodic", "--json")
    assert rc == 0
    d = json.loads(out)["sheet"]
    p = Params(sigma=9 / 125, cells=256, shape=(16, 16), lattice="square", boundary="periodic")
    th = Theory("lattice", True, True, 0.0)
    assert d["topology"] == "16 x 16 square sheet (256 cells, periodic edges)"
    assert d["annulus"]["lambda_cells"] == pytest.approx(sheet.annulus(p, th)["lambda_cells"])
    assert d["fastest"]["lambda_cells"] == pytest.approx(sheet.fastest(p, th)["lambda_cells"])
    fs = d["finite_sheet"]
    assert fs["in_annulus"] and abs(fs["relative_to_fastest"]) <= 0.25
    assert all(m["growth_per_s"] > 0 for m in fs["unstable_modes"])
    rc, out, _ = run(capsys, "--sigma", "9/125", "--sheet", "8x10", "--lattice", "hex")
    assert rc == 0 and "8 x 10 hexagonal sheet (80 cells, open edges)" in out and "fastest sheet mode" in out


@pytest.mark.parametrize(
    "argv",
    [
        ("--sheet", "16"),
        ("--sheet", "0x4"),
        ("--sheet", "2x2", "--boundary", "periodic"),
        ("--lattice", "hex"),
        ("--scene", "no_such_scene"),
    ],
)
def test_sheet_bad_input_is_one_line_exit_2(capsys, argv):
    rc, out, err = run(capsys, *argv)
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1 and err.startswith("dispersion: error:")


def test_scene_gives_its_parameters_and_model(capsys):
    """--scene: the scene's parameters and model (the default scene runs the hil model)."""
    rc, out, _ = run(capsys, "--scene", "default", "--json")
    d = json.loads(out)
    assert rc == 0 and d["theory"].startswith("hil:") and "sheet" not in d
    rc, out, _ = run(capsys, "--scene", "default", "--model", "lattice", "--json")
    assert json.loads(out)["theory"] == "lattice with inertia"
