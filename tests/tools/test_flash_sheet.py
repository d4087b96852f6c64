"""Flashing tool for a sheet: an inventory of N cells (up to 64) + primary, its plan (each cell its own address, the
primary built to poll N) and a flash of a fake 32-cell rig; the rig as built (16 cells) stays as it was."""

from __future__ import annotations

import json

import pytest

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import inventory as inv
from metacell_tools.flash import runner as rn
from metacell_tools.flash.plan import PlanError, describe, make_plan, parse_only
from tests.tools.flash_fakes import FakeRig, fake_inventory, fake_ports, run_flash, write_ports_json


def test_inventory_of_a_sheet_roundtrips_and_the_rig_as_built_keeps_its_file(tmp_path):
    path = tmp_path / "b.json"
    inv.save(path, fake_inventory())
    assert "cells" not in json.loads(path.read_text())  # 16 cells: the file reads as before sheets
    assert inv.read(path) == (fake_inventory(), 16)
    sheet = fake_inventory(64)
    inv.save(path, sheet, 64)
    assert json.loads(path.read_text())["cells"] == 64 and inv.read(path) == (sheet, 64)
    assert [b.addr for b in sheet if b.cell in (17, 64)] == [0x20, 0x4F]
    with pytest.raises(inv.InventoryError, match=r"cell must be 1..16, got 17"):
        inv.validate(sheet)  # the same boards on a 16-cell rig
    with pytest.raises(inv.InventoryError, match=r"cells must be 1..64"):
        inv.validate([], 65)
    for bad in (0, 65, True, "32"):
        path.write_text(json.dumps({"format": inv.FORMAT, "cells": bad, "boards": []}))
        with pytest.raises(inv.InventoryError, match="cells must be"):
            inv.read(path)
    assert inv.assign([], "NEW", "40", cells=64) == [inv.Board("NEW", "cell", 40)]
    with pytest.raises(inv.InventoryError, match=r"cell must be 1..32, got 33"):
        inv.assign([], "NEW", "33", cells=32)


def test_inventory_cli_sets_the_cell_count_and_refuses_what_does_not_fit(tmp_path, capsys):
    ports = write_ports_json(tmp_path / "p.json", fake_ports(2))
    path = tmp_path / "b.json"
    args = ["inventory", "--inventory", str(path), "--ports-json", str(ports)]
    assert cli.main(args + ["--cells", "32"]) == 0
    assert "the rig has 32 cells (addresses 0x10..0x2f) + primary" in capsys.readouterr().out
    assert cli.main(args + ["--assign", "20", "--serial", "SN01"]) == 0
    assert inv.read(path) == ([inv.Board("SN01", "cell", 20)], 32)
    before = path.read_text()
    for bad in (["--assign", "33", "--serial", "SN00"], ["--cells", "65"], ["--cells", "0"], ["--cells", "16"]):
        assert cli.main(args + bad) == cli.EXIT_USAGE, bad
        assert path.read_text() == before  # nothing changed
    err = capsys.readouterr().err
    assert "cell must be 1..32, got 33" in err and "cells must be 1..64" in err
    assert "--cells 16: the inventory still has cell 20 (0x23)" in err
    assert cli.main(args + ["--cells", "64", "--assign", "64", "--serial", "SN00"]) == 0  # both at once
    assert inv.read(path) == ([inv.Board("SN01", "cell", 20), inv.Board("SN00", "cell", 64)], 64)


def test_plan_for_32_cells_and_primary(tmp_path, capsys):
    """33 boards: cells 1..32 at 0x10..0x2F, each its own build; the primary built with -DMC_RIG_CELLS=32."""
    plan = make_plan(fake_inventory(32), fake_ports(33), cells=32)
    assert len(plan.steps) == 33 and plan.cells == 32
    for j, step in enumerate(plan.steps[:32], start=1):
        env = dict(step.env_vars)
        assert (step.board.cell, step.board.addr, step.env_name) == (j, 0x10 + j - 1, "cell")
        assert env["PLATFORMIO_BUILD_SRC_FLAGS"] == f"-DMC_CELL_INDEX={j} -DMC_CELL_ADDR=0x{0x10 + j - 1:02x}"
        assert step.port.serial_number == f"SN{j - 1:02d}"
    primary = dict(plan.steps[32].env_vars)
    assert plan.steps[32].board.role == "primary" and plan.steps[32].port.serial_number == "SN32"
    assert primary["PLATFORMIO_BUILD_SRC_FLAGS"] == "-DMC_RIG_CELLS=32"
    assert primary["PLATFORMIO_BUILD_DIR"].endswith("build-primary-32cells")
    text = describe(plan)
    assert text.startswith("33 board(s) to flash (a rig of 32 cells + primary):")
    assert "cell 32 addr 0x2f" in " ".join(text.split())
    rig16 = dict(make_plan(fake_inventory(), fake_ports(17)).steps[16].env_vars)  # the rig as built: as before
    assert rig16["PLATFORMIO_BUILD_SRC_FLAGS"] == "" and rig16["PLATFORMIO_BUILD_DIR"].endswith("build-primary")
    assert parse_only("17-32,primary", 32) == set(range(17, 33)) | {"primary"}
    with pytest.raises(PlanError, match="outside cells 1..32"):
        parse_only("30-33", 32)
    with pytest.raises(PlanError, match="outside cells 1..16"):
        parse_only("17")
    inv.save(tmp_path / "b.json", fake_inventory(32), 32)
    ports = write_ports_json(tmp_path / "p.json", fake_ports(33))
    base = ["--inventory", str(tmp_path / "b.json"), "--ports-json", str(ports), "--pio", "pio"]
    assert cli.main(["flash", *base, "--prebuilt", str(tmp_path), "--uploader", "bossac"]) == cli.EXIT_USAGE
    assert "--prebuilt: the images are the 16-cell rig's; this rig has 32 cells" in capsys.readouterr().err


def test_flash_a_fake_32_cell_rig(tmp_path):
    """Every board of a 32-cell rig is built, uploaded and answers with its own cell and address."""
    rig = FakeRig(fake_inventory(32), fake_ports(33))
    outcomes, _ = run_flash(rig, stop_on_error=True, tmp_path=tmp_path, cells=32)
    assert [o.status for o in outcomes] == [rn.OK] * 33
    assert rig.flashed["SN31"] == ("cell", 32, 0x2F) and rig.flashed["SN32"] == ("primary", None, None)
    primary_env = next(env for argv, env in rig.runs if argv[argv.index("-e") + 1] == "primary")
    assert primary_env["PLATFORMIO_BUILD_SRC_FLAGS"] == "-DMC_RIG_CELLS=32"
    assert "33 of 33 board(s) flashed and verified" in rn.summary(outcomes)
