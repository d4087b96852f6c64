"""`dispersion` command: JSON contract, overrides, human table, clean errors."""

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis.cli import dispersion_main, parse_set
from host_emulator.analysis.stability import dispersion
from host_emulator.params import Params


def run(capsys, *argv):
    rc = dispersion_main(list(argv))
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_json_contract_and_values(capsys):
    rc, out, _ = run(capsys, "--sigma", "9/125", "--json")
    assert rc == 0
    d = json.loads(out)
    for k in ("regime", "fastest_lambda_cells", "fastest_growth_per_s", "oscillation_period_s", "unstable_band_cells"):
        assert k in d
    ref = dispersion(Params(sigma=9 / 125))
    assert d["regime"] == "conditionally_unstable"
    assert d["fastest_lambda_cells"] == pytest.approx(ref["fastest_lambda_cells"])
    assert d["unstable_band_cells"] == pytest.approx(ref["unstable_band_cells"])


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
    assert rc == 0 and d["model"] == "continuum" and d["inertia"] is True and d["regime"] == "stable"
    assert d["fastest_growth_per_s"] == pytest.approx(ref["fastest_growth_per_s"])
    assert len(d["lattice_modes"]) == 16
    rc, out, _ = run(capsys, "--sigma", "0.112", "--inertia", "--json")
    assert json.loads(out)["regime"] == "unconditionally_unstable"


def test_human_table(capsys):
    rc, out, _ = run(capsys, "--sigma", "6/125")
    assert rc == 0 and "unconditionally unstable" in out and "inf]" in out


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
