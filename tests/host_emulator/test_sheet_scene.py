"""2-D sheets in scenes: cells = [rows, cols], lattice and boundary, per-cell values as rows, pushes at (row, col);
every bad value one line naming the key; the records say what the scene gave and an old chain's records are as they
were."""

import copy
import json
import tomllib

import numpy as np
import pytest

from host_emulator.cli import main
from host_emulator.models import ConfigError
from host_emulator.scene import SCENE_DIR, load_scene, scene_from_dict, scene_table
from host_emulator.topology import Topology

BASE = tomllib.loads((SCENE_DIR / "exp3_single_sigma9.toml").read_text())


def sheet(**top) -> dict:
    d = copy.deepcopy(BASE)
    d.update(top)
    return d


def test_cells_rows_cols_is_a_square_sheet_and_set_parses_the_list():
    sc = load_scene("exp3_single_sigma9", ["cells=[16,16]"])
    assert sc.cells == 256 and sc.params.cells == 256
    assert sc.params.shape == (16, 16) and sc.params.lattice == "square" and sc.params.boundary == "open"
    assert sc.topology == Topology((16, 16), "square", False)
    hexp = load_scene("exp3_single_sigma9", ["cells=[6,5]", 'lattice="hex"', 'boundary="periodic"'])
    assert hexp.topology == Topology((6, 5), "hex", True) and hexp.cells == 30
    ring = load_scene("exp3_single_sigma9", ['boundary="periodic"'])
    assert ring.topology == Topology((16,), "chain", True) and ring.params.shape == ()


def test_the_record_keeps_cells_as_given_and_an_old_chains_record_is_unchanged():
    old = load_scene("exp3_single_sigma9").as_dict()
    assert old["cells"] == 16 and "lattice" not in old and "boundary" not in old
    # the record of a chain is what it was before Params knew its topology: no shape, lattice or boundary in params
    assert not {"shape", "lattice", "boundary"} & set(old["params"]) and old["params"]["cells"] == 16
    d = load_scene("exp3_single_sigma9", ["cells=[4,6]", 'lattice="hex"']).as_dict()
    assert (d["cells"], d["lattice"], d["boundary"]) == ([4, 6], "hex", "open") and d["params"]["cells"] == 24
    # a sheet's params name its lattice too (summary.json records the params): what Params holds
    assert (d["params"]["shape"], d["params"]["lattice"], d["params"]["boundary"]) == ([4, 6], "hex", "open")
    ring = load_scene("exp3_single_sigma9", ['boundary="periodic"']).as_dict()
    assert (ring["cells"], ring["lattice"], ring["boundary"]) == (16, "chain", "periodic")
    json.dumps(d)  # JSON-ready


@pytest.mark.parametrize("over", [[], ["cells=[4,6]", 'lattice="hex"', 'boundary="periodic"'], ['boundary="periodic"']])
def test_a_scene_read_back_from_its_table_is_the_same(over):
    """scene_table -> scene_from_dict (what he.load_scene(scene, overrides) does) keeps the lattice; on main before
    this change the round trip of any scene failed on params.shape = []."""
    sc = load_scene("exp3_single_sigma9", over)
    back = scene_from_dict(scene_table(sc), sc.source)
    assert back == sc


def test_per_cell_values_as_a_flat_list_or_as_rows():
    rows = [[0.01 * (r * 3 + c + 1) for c in range(3)] for r in range(2)]
    flat = [x for r in rows for x in r]
    a = scene_from_dict(sheet(cells=[2, 3], perturbation=[], params={"sigma": rows}))
    b = scene_from_dict(sheet(cells=[2, 3], perturbation=[], params={"sigma": flat}))
    assert a.params.sigma == b.params.sigma == tuple(flat)
    assert a.params.per_cell("sigma")[a.topology.cell_of(2, 1) - 1] == pytest.approx(0.04)
    c = load_scene("exp3_single_sigma9", ["cells=[2,3]", "perturbation.1.cell=5", "params.sigma.5=0.09"])
    assert c.params.per_cell("sigma")[4] == 0.09 and c.params.per_cell("sigma")[3] == pytest.approx(0.072)


def test_a_push_at_row_and_col_is_that_cell_and_is_recorded_as_given():
    d = sheet(cells=[16, 16])
    d["perturbation"] = [{**{k: v for k, v in BASE["perturbation"][0].items() if k != "cell"}, "row": 8, "col": 9}]
    sc = scene_from_dict(d)
    (q,) = sc.perturbations
    assert q.cell == (8 - 1) * 16 + 9 == sc.topology.cell_of(8, 9) and (q.row, q.col) == (8, 9)
    rec = sc.as_dict()["perturbation"][0]
    assert rec["row"] == 8 and rec["col"] == 9 and "cell" not in rec
    # cell = N still works on a sheet, and --set moves a push from cell to (row, col) and back
    assert load_scene("exp3_single_sigma9", ["cells=[16,16]"]).perturbations[0].cell == 8
    moved = load_scene("exp3_single_sigma9", ["cells=[16,16]", "perturbation.1.row=2", "perturbation.1.col=3"])
    assert moved.perturbations[0].cell == 19 and moved.as_dict()["perturbation"][0]["row"] == 2
    back = load_scene("exp3_single_sigma9", ["cells=[16,16]", "perturbation.1.row=2", "perturbation.1.col=3",
                                             "perturbation.1.cell=7"])  # fmt: skip
    assert back.perturbations[0].cell == 7 and back.perturbations[0].row == 0


@pytest.mark.parametrize(
    ("over", "needle"),
    [
        (["cells=[0,4]"], "cells = [0, 4]"),
        (["cells=[4,4,4]"], "cells = [4, 4, 4]"),
        (['cells=[4,"x"]'], "cells"),
        (["cells=[300,300]"], "cells = [300, 300]"),
        (["cells=0"], "cells = 0"),
        (["cells=true"], "cells = True"),
        (['lattice="hex"'], "lattice = 'hex'"),
        (["cells=[4,4]", 'lattice="triangle"'], "lattice 'triangle'"),
        (["cells=[4,4]", 'lattice="chain"'], "lattice = 'chain'"),
        (["cells=[4,4]", "lattice=3"], "lattice = 3"),
        (['boundary="closed"'], "boundary = 'closed'"),
        (["boundary=1"], "boundary = 1"),
        (["cells=[2,4]", 'boundary="periodic"'], "periodic sheet"),
        (["cells=2", 'boundary="periodic"'], "ring"),
        (["params.shape=[4,4]"], "params.shape"),
        (['params.lattice="hex"'], "params.lattice"),
        (["cells=[4,4]", "perturbation.1.cell=17"], "perturbation[1].cell = 17"),
        (["cells=[4,4]", "perturbation.1.row=5", "perturbation.1.col=1"], "perturbation[1].row = 5"),
        (["cells=[4,4]", "perturbation.1.row=1", "perturbation.1.col=0"], "perturbation[1].col = 0"),
        (["cells=[4,4]", "perturbation.1.row=1"], "row without col"),
        (["perturbation.1.row=1", "perturbation.1.col=1"], "perturbation[1].row"),
        (["cells=[4,4]", "params.sigma=[[0.1,0.1],[0.1,0.1]]"], "params.sigma: 2 rows"),
        (["cells=[2,2]", "params.sigma=[[0.1,0.1],[0.1]]"], "params.sigma[2] (row 2)"),
        (["cells=[2,2]", "params.sigma=[[0.1,0.1],[0.1,true]]"], "params.sigma[2][2] (row 2, col 2)"),
        (["cells=[2,2]", "params.sigma=[0.1,0.1,0.1]"], "params.sigma: 3 values for 4 cells"),
    ],
)
def test_every_bad_value_is_one_line_naming_the_key(over, needle, tmp_path, capsys):
    with pytest.raises(ConfigError) as e:
        load_scene("exp3_single_sigma9", over)
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)
    out = tmp_path / "o"
    argv = ["run", "exp3_single_sigma9", "--quiet", "--out", str(out)]
    assert main([*argv, *[x for o in over for x in ("--set", o)]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert not out.exists()


def test_a_push_on_a_sheet_and_a_scene_table_with_rows_and_cols_round_trip():
    d = sheet(cells=[5, 7], lattice="hex")
    d["perturbation"] = [{**{k: v for k, v in BASE["perturbation"][0].items() if k != "cell"}, "row": 5, "col": 7}]
    sc = scene_from_dict(d)
    assert sc.perturbations[0].cell == 35
    assert scene_from_dict(scene_table(sc)) == dataclasses_replace_source(sc)


def dataclasses_replace_source(sc):
    import dataclasses

    return dataclasses.replace(sc, source="")


def test_the_chains_per_cell_values_and_pushes_are_as_before():
    sc = load_scene("exp3_single_sigma9", ["params.sigma.3=0.05"])
    assert sc.params.shape == () and sc.params.lattice == "chain"
    assert np.count_nonzero(sc.params.per_cell("sigma") == 0.05) == 1
    assert sc.perturbations[0].as_dict() == dict(BASE["perturbation"][0])


def test_a_sheets_cell_steps_weigh_its_bonds():
    """The run limit counts a sheet's cell steps at what they cost (the plant's edge list: about twice the open
    chain's per cell on a square sheet): a step the 4096-cell chain may take for 15 s is refused on a 64 x 64 sheet."""
    from host_emulator.limits import cell_weight, check_run

    over = ["t_end_s=15", "model_options.dt=1e-5", 'model_options.stepper="symplectic_euler"']
    chain = load_scene("exp3_single_sigma9", [*over, "cells=4096"])
    sheet = load_scene("exp3_single_sigma9", [*over, "cells=[64,64]"])
    assert cell_weight(chain) == 1.0 and cell_weight(sheet) == pytest.approx(0.5 + 0.8 * 8064 / 4096)
    assert check_run(chain) is None
    problem = check_run(sheet)
    assert problem is not None and "model_options.dt = 1e-05 s" in problem and "cell steps" in problem


def test_a_faults_cell_on_a_sheet_may_be_row_and_col():
    """parse_fault takes a sheet's (row, col) as parse_perturbation does (the image tier, the one that injects faults,
    runs sheets of up to the rig's 16 boards and refuses larger ones: this is the parser alone)."""
    from host_emulator.models.options import parse_fault

    topo = Topology((4, 4), "square")
    assert parse_fault({"kind": "tick_dead", "start_s": 0.1, "row": 2, "col": 3}, topo, "fault[1]").board == "cell7"
    assert parse_fault({"kind": "hardfault", "start_s": 0.1, "cell": 16}, topo, "fault[1]").board == "cell16"
    with pytest.raises(ConfigError, match=r"fault\[1\]: give cell or row and col, not both"):
        parse_fault({"kind": "tick_dead", "start_s": 0.1, "cell": 2, "row": 1, "col": 1}, topo, "fault[1]")
    with pytest.raises(ConfigError, match=r"fault\[1\]\.row"):
        parse_fault({"kind": "tick_dead", "start_s": 0.1, "row": 1, "col": 1}, 16, "fault[1]")
    with pytest.raises(ConfigError, match=r"model = 'image' with cells = \[8, 8\]"):
        load_scene("sheet_8x8", ["model=image"])
