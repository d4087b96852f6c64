"""`design --sheet`: the sheet target's parser (bad input one line, exit 2, nothing written), the landing criterion
on hand-made fields, the linear first guess on an 8 x 8 sheet, and a short verification of the shipped 16 x 16
design's laws on two draws of the rig's uncertainty."""

import dataclasses

import numpy as np
import pytest

from host_emulator.cli import main as emulator_main
from host_emulator.workbench.design import DesignError
from host_emulator.workbench.design.sheet_driver import sheet_base
from host_emulator.workbench.design.sheet_landing import interior_cells, sheet_lands, sheet_miss_reason
from host_emulator.workbench.design.sheet_linear import (
    REST_SHARE_MAX,
    mode_rest_share,
    sheet_fastest_modes,
    sheet_first_guess,
    sheet_linear_score,
)
from host_emulator.workbench.design.sheet_runs import sheet_scene, sheet_verify
from host_emulator.workbench.design.sheet_target import (
    SheetPush,
    parse_region,
    parse_shape,
    parse_sheet_pushes,
    parse_sheet_target,
)
from host_emulator.workbench.design.space import Space


def test_regions_parse_in_row_major_cells():
    assert parse_shape("16x16") == (16, 16) and parse_shape("8X4") == (8, 4)
    assert parse_region("cols=3-4", (2, 4)) == (3, 4, 7, 8)
    assert parse_region("rows=2", (3, 2)) == (3, 4)
    assert parse_region("1-2x2-3", (3, 3)) == (2, 3, 5, 6)
    assert parse_region("rows=1+cols=3", (3, 3)) == (1, 2, 3, 6, 9)
    t = parse_sheet_target("lambda=8", (16, 16), "cols=9-16")
    assert t.lam == 8 and len(t.rest) == 128 and t.text() == "lambda=8 rest=cols=9-16"
    assert t.pattern_box() == (slice(0, 16), slice(0, 8))
    assert parse_sheet_target("pattern", (8, 8), "1-4x1-4").pattern_box() is None  # an L-shaped pattern region
    assert parse_sheet_pushes("8x4,2x2:-", t) == (SheetPush(8, 4, 1), SheetPush(2, 2, -1))


@pytest.mark.parametrize(
    "target, rest, push, said",
    [
        ("pattern", "cols=9-17", "8x4", "must lie in 1..16"),
        ("pattern", "cols=1-16", "8x4", "covers the whole sheet"),
        ("pattern", "diag=1-3", "8x4", "expected rows=A-B"),
        ("pattern", None, "8x4", "needs the region that rests"),
        ("lambda=1", "cols=9-16", "8x4", "lambda must lie in 2..32"),
        ("walls=5.5", "cols=9-16", "8x4", "expected pattern or lambda=N"),
        ("pattern", "cols=9-16", "8x12", "lies in the rest region"),
        ("pattern", "cols=9-16", "8x4,8x4", "distinct cells"),
        ("pattern", "cols=9-16", "17x4", "outside the 16 x 16 sheet"),
    ],
)
def test_bad_sheet_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, target, rest, push, said):
    out = tmp_path / "d"
    argv = ["design", "--sheet", "16x16", "--target", target, "--push", push, "--out", str(out)]
    assert emulator_main(argv + (["--rest", rest] if rest else [])) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1 and err.startswith("design: error:"), err
    assert not out.exists()


def test_bad_sheet_size_is_refused():
    for bad in ("16", "16x", "1x16", "axb"):
        with pytest.raises(DesignError, match="--sheet"):
            parse_shape(bad)


def _stripes(target, lam=8.0, amp=0.6):
    """Stripes along the rows (their crests on rows) in the pattern region, zero on the rest region."""
    rows, cols = target.shape
    r = np.repeat(np.arange(1, rows + 1), cols)
    u = amp * np.cos(2 * np.pi * (r - 0.5) / lam)
    return np.where(target.rest_mask(), 0.0, u)


def test_landing_on_hand_made_fields():
    t = parse_sheet_target("pattern", (8, 8), "cols=5-8")
    u = _stripes(t)
    assert sheet_lands(t, u)
    assert sheet_miss_reason(t, u, steady=False) == "moving"
    assert sheet_miss_reason(t, u, torque_ok=False) == "torque limit"
    moved = u.copy()
    moved[t.topology.cell_of(3, 6) - 1] = 0.11  # one rest cell beyond 0.1 rad
    assert sheet_miss_reason(t, moved) == "rest region moved"
    assert sheet_miss_reason(t, 0.2 * u) == "at rest"  # the pattern region below 0.3 rad everywhere
    hole = u.copy()
    hole[t.topology.cell_of(1, 2) - 1] = 0.05  # a cell beside neither a wall nor the rest region, near zero
    assert sheet_miss_reason(t, hole) == "region not filled"
    edge = u.copy()
    edge[t.topology.cell_of(1, 4) - 1] = 0.05  # beside the rest region: the pattern's edge may fall off there
    assert not interior_cells(t, edge)[t.topology.cell_of(1, 4) - 1] and sheet_lands(t, edge)
    assert sheet_lands(parse_sheet_target("lambda=8", (8, 8), "cols=5-8"), u)
    assert sheet_miss_reason(parse_sheet_target("lambda=4", (8, 8), "cols=5-8"), u) == "wavelength"
    assert sheet_miss_reason(parse_sheet_target("lambda=4", (8, 8), "cols=5-8"), _stripes(t, 4.0)) is None


@pytest.fixture(scope="module")
def base8():
    return sheet_base("default", (8, 8))


def test_linear_first_guess_puts_the_fastest_mode_in_the_pattern_region(base8):
    t = parse_sheet_target("pattern", (8, 8), "cols=5-8")
    space = Space(base8.params, ("sigma", "k_ab", "k2"), ("sigma", "k_ab", "k2"), t.segments())
    # the uniform source law patterns everywhere: its fastest mode spreads over the rest region too
    uniform = sheet_fastest_modes(base8.params, 1)[0]
    assert mode_rest_share(uniform["alpha"], t) > 0.5 and sheet_linear_score(base8.params, t)[0] < 1
    x, score, facts = sheet_first_guess(space, t, seed=1, maxiter=5)
    assert score > 1 and facts["rest_growth_per_s"] < -1 and facts["rest_growth_lattice_per_s"] < -1
    top, nxt = sheet_fastest_modes(space.params(x), 2)
    assert top["kind"] == "stationary" and top["growth_per_s"] >= 1
    assert mode_rest_share(top["alpha"], t) < REST_SHARE_MAX


# the shipped 16 x 16 design (docs/design.md, "Sheets"): the pattern region's and the rest region's laws
SHIPPED = {
    "pattern": {"sigma": 0.041875, "k_ab": 0.016943, "k2": -0.08861},
    "rest": {"sigma": 0.177738, "k_ab": 0.119987, "k2": 0.012407},
}


# docs/design.md's lambda=12 design (its laws quoted there too)
LAMBDA_12 = {
    "pattern": {"sigma": 0.096923, "k_ab": 0.020038, "k2": -0.119797},
    "rest": {"sigma": 0.170036, "k_ab": 0.116219, "k2": 0.025014},
}


@pytest.mark.parametrize("target, laws, t_end", [("pattern", SHIPPED, 5.0), ("lambda=12", LAMBDA_12, 10.0)])
def test_sheet_designs_land_on_two_draws(target, laws, t_end):
    """The two 16 x 16 designs of docs/design.md, run briefly on two draws of the rig's uncertainty: both land (the
    lambda=12 one at its wavelength)."""
    t = parse_sheet_target(target, (16, 16), "cols=9-16")
    base = sheet_base("default", (16, 16))
    rest = t.rest_mask()
    kw = {k: tuple(laws["rest"][k] if r else laws["pattern"][k] for r in rest) for k in laws["rest"]}
    p = dataclasses.replace(base.params, **kw)
    sc = sheet_scene(dataclasses.replace(base, t_end_s=t_end), p, parse_sheet_pushes("8x4", t), 0.02, 0.1, None)
    v = sheet_verify(sc, t, 2, pushes_too=False)
    assert v["fraction_seeds"] == 1.0, [(r["why"], r.get("error")) for r in v["runs"]]
    assert all(r["pattern_kind"] != "rest" and r["torque_fraction"] <= 1 for r in v["runs"])


@pytest.mark.parametrize("target, laws", [("pattern", SHIPPED), ("lambda=12", LAMBDA_12)])
def test_docs_sheet_rows_quote_the_laws(target, laws):
    """docs/design.md's 2-D rows name these laws (and 100 % of 20 draws and 12 pushes)."""
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[3] / "docs" / "design.md").read_text()
    cmd = f"`design --sheet 16x16 --target {target} --rest cols=9-16 --push 8x4` (2-D)"
    row = re.search(r"^\| " + re.escape(cmd) + r" \| (.*)$", page, re.M)
    assert row, f"docs/design.md: the row of {cmd} moved"
    assert "100 % of 20 / 100 % of 12" in row.group(1)
    for region, cols in (("pattern", "1-8"), ("rest", "9-16")):
        law = laws[region]
        assert f"cols {cols}: sigma {law['sigma']:g}, k_ab {law['k_ab']:g}, k2 {law['k2']:g}" in row.group(1)


def test_search_does_not_run_a_candidate_off_the_linear_constraints(base8):
    """The uniform source law (its rest region patterns too) scores below 1 in the linear theory: the search
    ranks it below every candidate it runs, without running it."""
    from host_emulator.workbench.design.sheet_runs import sheet_search

    t = parse_sheet_target("pattern", (8, 8), "cols=5-8")
    space = Space(base8.params, ("sigma", "k_ab", "k2"), ("sigma", "k_ab", "k2"), t.segments())
    x, score, hist, runs = sheet_search(space, t, parse_sheet_pushes("4x2", t), base8, space.x0(), maxiter=0)
    assert runs == 0 and score < 0 and hist == [{"fraction": 0.0, "misses": ["linear theory"]}]


def test_written_scene_loads_back_as_designed(tmp_path):
    """scene.toml of a sheet design (cells = [rows, cols], per-cell values row by row, pushes at row and col) is
    the scene `run` loads: the same per-cell laws, pushes and firmware settings."""
    from host_emulator.scene import load_scene
    from host_emulator.workbench.design.sheet_driver import _write, sheet_table

    t = parse_sheet_target("pattern", (3, 4), "cols=3-4")
    base = sheet_base("default", (3, 4))
    p = dataclasses.replace(base.params, sigma=tuple(0.17 if r else 0.05 for r in t.rest_mask()), k2=-0.07)
    pushes = parse_sheet_pushes("2x1,3x2:-", t)
    sc = sheet_scene(base, p, pushes, 0.02, 0.1, None)
    path = tmp_path / "scene.toml"
    _write(path, sheet_table(sc, t, pushes, "d", "a sheet design"), t)
    back = load_scene(str(path))
    assert back.params.shape == (3, 4) and back.params.lattice == "square" and back.model == "hil"
    assert np.array_equal(back.params.per_cell("sigma"), p.per_cell("sigma")) and back.params.k2 == -0.07
    assert [(q.cell, q.row, q.col, q.torque_Nm) for q in back.perturbations] == [(5, 2, 1, 0.02), (10, 3, 2, -0.02)]
    assert back.params.bemf_comp is False and back.options.stepper == base.options.stepper


def test_he_design_takes_a_sheet_as_the_command_does(monkeypatch, tmp_path):
    """he.design(..., sheet="ROWSxCOLS") is `design --sheet`: design_sheet with the sheet's defaults (4 search seeds,
    4 generations, out/design_sheet) and the caller's values; a chain's own options are refused in one line, and a
    bad sheet is refused before anything is written."""
    import host_emulator as he
    from host_emulator.workbench.design import sheet_driver

    got: dict = {}
    monkeypatch.setattr(sheet_driver, "design_sheet", lambda *a, **kw: got.update(args=a, **kw) or {"ok": 1})
    assert he.design("pattern", push="8x4", sheet="16x16", rest="cols=9-16", seeds=3) == {"ok": 1}
    assert got["args"] == ("pattern", "8x4") and got["sheet"] == "16x16" and got["rest"] == "cols=9-16"
    assert (got["seeds"], got["search_seeds"], got["maxiter"], got["out"]) == (3, 4, 4, "out/design_sheet")
    he.design("lambda=6", push="2x2", sheet="4x4", maxiter=0, search_seeds=2, out=str(tmp_path / "d"))
    assert (got["search_seeds"], got["maxiter"], got["out"]) == (2, 0, str(tmp_path / "d"))
    for bad in ({"per_cell": ("sigma",)}, {"scheduler": "tcp://x:1"}, {"push": (8,)}):
        with pytest.raises(DesignError) as e:
            he.design("pattern", **{"push": "8x4", **bad}, sheet="16x16", rest="cols=9-16")
        assert "\n" not in str(e.value)
    monkeypatch.undo()
    with pytest.raises(DesignError):
        he.design("pattern", push="2x2", sheet="1x1", out=str(tmp_path / "never"))
    assert not (tmp_path / "never").exists()
