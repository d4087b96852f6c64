"""Docs that stay true: every figure of docs/emulator.md's table of shipped scenes (model, outcome, pattern period,
walls and their bonds) is what a fresh run of that scene reports, every shipped scene has its row (a sheet in the
sheet table, checked against its scene file: model, size, push), and the scene format's `cells` range is the one
the code accepts."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "emulator.md").read_text()
CELL = r"((?:\\\||[^|])+?)"  # a table cell: anything but a bare |, escaped \| included
ROW = re.compile(rf"^\| `(\w+)` \| (\w+) \| {CELL} \| {CELL} \| {CELL} \| {CELL} \|$", re.M)


def _rows() -> dict[str, tuple[str, ...]]:
    start = DOC.index("| scene | model | what it is | outcome | pattern period | walls |")
    table = DOC[start : DOC.index("\n\n", start)]
    return {m.group(1): (m.group(2), *m.groups()[3:]) for m in ROW.finditer(table)}


def _outcome(s: dict) -> str:
    if s["at_rest"]:
        return f"at rest, max \\|alpha\\| {s['amplitude_rad']:.2g} rad"
    if s["steady"] and s["domain_walls"]:
        return "steady pattern"
    return "moving"


SHEET_ROW = re.compile(rf"^\| `(\w+)` \| (\w+) \| {CELL} \| (\d+) x (\d+) \| \((\d+), (\d+)\) \|$", re.M)


def _sheet_rows() -> dict[str, tuple[str, ...]]:
    start = DOC.index("| scene | model | what it is | cells | push at (row, col) |")
    table = DOC[start : DOC.index("\n\n", start)]
    return {m.group(1): (m.group(2), *m.groups()[3:]) for m in SHEET_ROW.finditer(table)}


def test_every_shipped_scene_has_a_row():
    import host_emulator as he

    assert not set(_rows()) & set(_sheet_rows())
    assert sorted([*_rows(), *_sheet_rows()]) == sorted(he.list_scenes())


@pytest.mark.parametrize("name", sorted(_sheet_rows()))
def test_the_sheet_tables_rows_are_the_scene_files(name):
    from host_emulator.scene import load_scene

    model, rows, cols, prow, pcol = _sheet_rows()[name]
    sc = load_scene(name)
    assert sc.model == model and sc.topology.shape == (int(rows), int(cols)) and sc.topology.is_sheet
    assert [(q.row, q.col) for q in sc.perturbations] == [(int(prow), int(pcol))]


@pytest.mark.parametrize("name", sorted(_rows()))
def test_the_scene_tables_figures_are_a_fresh_runs(name):
    import host_emulator as he

    model, outcome, period, walls = _rows()[name]
    r = he.run(name)
    s = r.summary
    assert model == r.scene.model, name
    assert outcome == _outcome(s), (name, s["at_rest"], s["steady"], s["amplitude_rad"])
    want_period = "-" if s["pattern_period_cells"] is None else f"{s['pattern_period_cells']:.2f} cells"
    assert period == want_period, name
    bonds = ", ".join(f"{b:g}" for b in s["domain_wall_bonds"])
    assert walls == (f"{s['domain_walls']} at {bonds}" if bonds else str(s["domain_walls"])), name


def test_the_cells_range_of_the_scene_format_is_the_codes():
    from host_emulator.models import ConfigError
    from host_emulator.scene import load_scene, scene_from_dict, scene_table

    lo, hi = map(int, re.search(r"^cells = 16 +# required, (\d+)\.\.(\d+)$", DOC, re.M).groups())
    base = scene_table(load_scene("default"))
    for ok in (lo, hi):
        assert scene_from_dict({**base, "cells": ok, "perturbation": []}).cells == ok
    for bad in (lo - 1, hi + 1):
        with pytest.raises(ConfigError, match="cells"):
            scene_from_dict({**base, "cells": bad, "perturbation": []})
