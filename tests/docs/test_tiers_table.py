"""docs/accuracy.md#tiers is what `python -m host_emulator.benchmarks.tiers` prints: every row's text and every
machine-independent figure (the errors, what each preset runs) recomputed here; the times are the command's run
on the machine the section names, and the constants `run` and `--model auto` quote (host_emulator/tiers.py)
are the table's."""

import re
from pathlib import Path

import numpy as np
import pytest

from host_emulator.accuracy import LEVELS
from host_emulator.benchmarks import tiers as tb
from host_emulator.scene import list_scenes, load_scene
from host_emulator.tiers import COST_MS_PER_SIM_S, ERROR_VS_UP_RAD, PRESET_ERROR_RAD, TIERS, UP, fmt_cost

ROOT = Path(__file__).resolve().parents[2]
TEXT = (ROOT / "docs" / "accuracy.md").read_text()
SECTION = TEXT.split("\n## Tiers", 1)[1].split("\n## ", 1)[0] if "\n## Tiers" in TEXT else ""
NUM = r"[\d.e+-]+"


def _tier_rows():
    return re.findall(rf"^\| (continuum|lattice|hil|image) \| ([^|]+?) \| ({NUM}) \| ([^|]+?) \|$", SECTION, re.M)


def _preset_rows():
    row = rf"^\| (lattice|hil) \| (fast|balanced|exact) \| ([^|]+?) \| ({NUM}) \| ([^|]+?) \|$"
    return re.findall(row, SECTION, re.M)


def test_the_tier_table_rows_and_constants():
    rows = _tier_rows()
    assert [r[0] for r in rows] == list(tb.TIER_ORDER)
    for tier, models, cost, err in rows:
        assert models == TIERS[tier]
        assert cost == fmt_cost(COST_MS_PER_SIM_S[tier]), tier
        assert err == (f"{ERROR_VS_UP_RAD[tier]:.2g} (vs {UP[tier]})" if tier in UP else "- (the top tier)"), tier


@pytest.mark.parametrize("tier", ["continuum", "lattice"])
def test_the_tier_errors_are_what_the_command_computes(tier):
    """The differences between tiers below the image (the image's row is the command's run: seconds of CPU)."""
    (row,) = [r for r in _tier_rows() if r[0] == tier]
    assert row[3] == f"{tb.tier_error(tier):.2g} (vs {UP[tier]})"


def test_the_preset_table_is_what_the_command_computes():
    rows = _preset_rows()
    assert [(r[0], r[1]) for r in rows] == [(t, lv) for t in ("lattice", "hil") for lv in LEVELS]
    for tier, level, runs, _cost, err in rows:
        sc = tb.scene_for(tier, level)
        assert runs == tb.preset_sets(sc), (tier, level)
        assert err == tb.fmt_err(tb.preset_error(tier, level)), (tier, level)
        assert err == tb.fmt_err(PRESET_ERROR_RAD[tier, level]), (tier, level)


def test_every_shipped_scene_has_its_preset_costs_and_the_exceptions_are_named():
    row = r"^\| (\w+) \| (lattice|hil) \| ([^|]+?) \| ([^|]+?) \| ([^|]+?) \| (yes|no)([^|]*?) \|$"
    rows = re.findall(row, SECTION, re.M)
    shipped = [
        n for n, m, _ in list_scenes() if m in ("lattice", "hil") and load_scene(n).cells <= tb.SCENE_TABLE_MAX_CELLS
    ]
    assert sorted(r[0] for r in rows) == sorted(shipped)
    table = SECTION[SECTION.index("| scene | model | fast |") :]
    block = re.match(r"(?:\|.*\n)+", table)
    assert block
    prose = table[block.end() :].split("\n\n")[1]  # the paragraph under the table
    for name, _model, *_c, order, note in rows:
        f, b = (tb.resolved(load_scene(name, [f"accuracy={lv}"])) for lv in ("fast", "balanced"))
        assert (note == " (fast = balanced: one loop)") == (f == b), name
        if order == "no":  # the docs say where the names do not match the cost
            assert f"`{name}`" in prose, name


@pytest.mark.parametrize("name", ["exp3_single_sigma9", "exp3_single_sigma6"])
def test_exact_makes_fewer_force_evaluations_than_balanced_where_the_scene_keeps_small_beta(name):
    """The machine-independent side of the exception the section names: dop853 at tol 1e-8 evaluates the forces
    less often than rk4 at a quarter of the limit (4 per step) on the lattice scenes that set small-angle beta."""
    from host_emulator.construct import build_solver
    from host_emulator.controller import run_solver

    n = {}
    for lv in ("balanced", "exact"):
        sc = load_scene(name, ["t_end_s=3", f"accuracy={lv}"])
        info = run_solver(build_solver(sc), sc.t_end_s).info
        n[lv] = info["force_evaluations"] if "force_evaluations" in info else 4 * round(3.0 / info["dt_s"])
    assert n["exact"] < n["balanced"]
    assert np.isfinite(n["exact"])


def test_the_questions_table_and_the_quoted_lines():
    """The questions table is the command's; the quoted `--model auto` line and error line are what run prints."""
    from host_emulator.accuracy import error_estimate, estimate_line
    from host_emulator.tiers import pick

    assert tb.questions_table() in SECTION
    assert f"    {pick('pattern')[1]}\n" in SECTION
    acc = {"level": "balanced", "error_estimate": error_estimate("hil", "balanced")}
    assert f"    {estimate_line(acc)}\n" in SECTION
