"""The rig config (rig/rig.toml) names the rig's topology: a 4 x 4 sheet's scene runs and is analysed as that sheet
(the experiment plan, its summary's params, the dataset), a logger capture carries it and decodes a bigger sheet's
cells; the rig as built (no config: a chain of 16) is unchanged; bad configs are one line, exit 2, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from host_emulator.scene import load_scene
from host_emulator.topology import Topology
from metacell_tools.experiment import cli as ecli
from metacell_tools.experiment.plan import PlanError
from metacell_tools.experiment.rig import AS_BUILT, on_rig, rig_topology
from metacell_tools.rigtools import rigconfig
from metacell_tools.rigtools.logger import cli as lcli
from protocol import capture
from protocol.capture import CSV_HEADER, format_rows


def _toml(tmp_path, text, name="rig.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_rig_config_reads_a_sheet_and_defaults_to_the_rig_as_built(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no rig/rig.toml here
    assert rigconfig.read() == rigconfig.AS_BUILT == {"cells": 16, "lattice": "chain", "boundary": "open"}
    assert rig_topology() == AS_BUILT == Topology.chain(16)
    (tmp_path / "rig").mkdir()
    (tmp_path / "rig" / "rig.toml").write_text("cells = [4, 4]\n")
    assert rigconfig.read() == {"cells": [4, 4], "lattice": "square", "boundary": "open"}
    t = rig_topology()
    assert (t.shape, t.kind, t.n, t.cell_of(2, 3)) == ((4, 4), "square", 16, 7)  # cell = (row - 1) * cols + col
    hexa = rigconfig.read(_toml(tmp_path, 'cells = [8, 8]\nlattice = "hex"\nboundary = "periodic"\n'))
    assert rigconfig.n_cells(hexa) == 64 and rig_topology(str(tmp_path / "rig.toml")).degree().max() == 6
    assert rigconfig.read(_toml(tmp_path, "cells = 32\n")) == {"cells": 32, "lattice": "chain", "boundary": "open"}


@pytest.mark.parametrize(
    "text, why",
    [
        ("cells = [8, 9]\n", "at most 64 cells"),
        ("cells = [0, 4]\n", "expected a number of cells or"),
        ("cells = [4, 4, 4]\n", "expected a number of cells or"),
        ('cells = "16"\n', "expected a number of cells or"),
        ("cells = 65\n", "at most 64 cells"),
        ("cells = true\n", "expected a number of cells or"),
        ('cells = [4, 4]\nlattice = "chain"\n', "is a square or hex"),
        ('cells = 16\nlattice = "square"\n', "is a chain"),
        ('cells = [4, 4]\nboundary = "closed"\n', "boundary"),
        ("cells = [4, 4]\nrows = 4\n", "unknown key(s) rows"),
        ("lattice = 'square'\n", "`cells` is missing"),
        ("cells = [4, 4\n", "not a readable TOML file"),
    ],
)
def test_bad_rig_configs_are_refused(tmp_path, text, why):
    with pytest.raises(rigconfig.RigConfigError, match=why.replace("(", r"\(").replace(")", r"\)")):
        rigconfig.read(_toml(tmp_path, text))
    with pytest.raises(PlanError):
        rig_topology(str(tmp_path / "rig.toml"))


def test_a_scene_on_a_4x4_rig_runs_and_is_analysed_as_the_sheet(tmp_path):
    sheet = Topology.from_spec([4, 4])
    sc = on_rig(load_scene("exp1_ccw_ccw"), sheet)
    assert sc.params.shape == (4, 4) and sc.params.topology == sheet and sc.cells == 16
    assert on_rig(load_scene("exp1_ccw_ccw"), AS_BUILT) == load_scene("exp1_ccw_ccw")  # as built: untouched
    with pytest.raises(PlanError, match=r"cells = 8: the rig is a 4 x 4 square sheet \(16 cells, open edges\)"):
        on_rig(load_scene("exp5_rest", ["cells=8"]), sheet)
    with pytest.raises(PlanError, match="the scene is a 4 x 4 square sheet .*; the rig is a 2 x 8 square sheet"):
        on_rig(sc, Topology.from_spec([2, 8]))
    with pytest.raises(PlanError, match="the rig is a chain of 16"):
        on_rig(sc, AS_BUILT)
    cfg = _toml(tmp_path, "cells = [4, 4]\n")
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--rig", str(cfg), "--channel", "x"])
    scene, plan = ecli._prepare(args)
    assert scene.params.shape == (4, 4) and plan.cells == list(range(1, 17))
    assert plan.topology == {"cells": [4, 4], "lattice": "square", "boundary": "open"}
    assert plan.as_dict()["topology"] == plan.topology and "shape" not in plan.not_settable
    from host_emulator.analysis.summary import summarize
    from host_emulator.result import RunResult

    t = np.linspace(0, 1, 20)
    s = summarize(scene, RunResult(t, np.zeros((20, 16)), np.zeros((20, 16)), 1.0, {}), source="rig")
    assert (s["params"]["shape"], s["params"]["lattice"]) == ([4, 4], "square")  # the summary names the sheet
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--channel", "x", "--rig", str(cfg)])
    big = _toml(tmp_path, "cells = [4, 8]\n", "big.toml")
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--channel", "x", "--rig", str(big)])
    with pytest.raises(PlanError, match=r"cells = 16: the rig is a 4 x 8 square sheet"):
        ecli._prepare(args)
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--channel", "x", "--set", "cells=32"])
    args.rig = str(_toml(tmp_path, "cells = 32\n", "chain32.toml"))
    scene, plan = ecli._prepare(args)  # a 32-cell chain rig runs a 32-cell scene
    assert plan.cells == list(range(1, 33)) and plan.topology == {"cells": 32, "lattice": "chain", "boundary": "open"}


def test_the_rig_as_built_plans_as_before(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--channel", "x"])
    scene, plan = ecli._prepare(args)
    assert scene == load_scene("exp1_ccw_ccw") and plan.topology is None and "topology" not in plan.as_dict()
    args = ecli.parser().parse_args(["run", "exp1_ccw_ccw", "--channel", "x", "--set", "cells=17"])
    with pytest.raises(PlanError, match="cells = 17: the rig has 16 cells"):
        ecli._prepare(args)


def test_experiment_cli_refuses_a_bad_rig_config(tmp_path, capsys):
    bad = _toml(tmp_path, "cells = [9, 9]\n")
    out = tmp_path / "out"
    rc = ecli.main(["run", "exp1_ccw_ccw", "--channel", "/dev/null@115200", "--rig", str(bad), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "at most 64 cells" in err[0] and not out.exists()


def _csv(path, cells, cycles=3):
    rows = np.array([(0, k, j, k * 0.03, 0.0, 10 + j, -j, 0) for k in range(cycles) for j in cells], dtype=float)
    path.write_text(CSV_HEADER + "".join(format_rows(rows)))
    return path


def test_logger_capture_of_a_sheet_carries_its_topology(tmp_path, capsys):
    """--repair of a 32-cell sheet's CSV with its rig config: every cell decoded, the NPZ names the sheet (and
    he.load reads it); without the config the cells above 16 are refused, as before sheets."""
    import host_emulator as he

    _csv(tmp_path / "cap.csv", range(1, 33))
    cfg = _toml(tmp_path, "cells = [4, 8]\n")
    assert lcli.main(["--repair", str(tmp_path / "cap"), "--rig", str(cfg)]) == 0
    z = np.load(tmp_path / "cap.npz")
    attrs = json.loads(str(z["attrs"]))
    assert attrs["topology"] == {"cells": [4, 8], "lattice": "square", "boundary": "open"}
    assert z["alpha_counts"].shape[1] == 32 and z["alpha_counts"][1, 31] == 42
    ds = he.load(tmp_path / "cap.npz")
    assert ds.attrs["topology"] == attrs["topology"]
    (tmp_path / "cap.npz").unlink()
    assert lcli.main(["--repair", str(tmp_path / "cap"), "--rig", str(tmp_path / "absent.toml")]) == 2
    assert lcli.main(["--repair", str(tmp_path / "cap")]) == 2  # the rig as built: cell 17 is no cell of it
    err = capsys.readouterr().err
    assert "absent.toml: not a readable TOML file" in err and "cell" in err.splitlines()[-1]
    assert not (tmp_path / "cap.npz").exists()
    _csv(tmp_path / "c16.csv", range(1, 17))
    assert lcli.main(["--repair", str(tmp_path / "c16")]) == 0
    assert "topology" not in json.loads(str(np.load(tmp_path / "c16.npz")["attrs"]))  # as built: as before


def test_a_decoder_takes_the_cells_of_its_rig_only():
    """A decoder of the rig as built ignores a bigger sheet's cell 17 (foreign to it, as before sheets); one of a
    32-cell rig takes it."""
    import can

    for n, want in ((16, [16]), (32, [16, 17])):
        dec = capture.SampleDecoder(n, report=lambda text: None)
        for j in (16, 17):
            data = bytes([1, 5, 0, 6, 0, 0, 0, 0])
            dec.feed(can.Message(arbitration_id=0x100 + j, data=data, is_extended_id=False, timestamp=1.0))
        dec.flush()
        assert [r[2] for r in dec.rows] == want


def test_the_shipped_sheet_scenes_run_on_a_rig_banded_as_they_are(tmp_path, monkeypatch):
    """sheet_4x4_rig needs a 4 x 4 rig config (the chain as built refuses it); sheet_8x8 a 64-cell one."""
    monkeypatch.chdir(tmp_path)
    args = ecli.parser().parse_args(["run", "sheet_4x4_rig", "--channel", "x"])
    with pytest.raises(PlanError, match=r"the scene is a 4 x 4 square sheet .*; the rig is a chain of 16 cells"):
        ecli._prepare(args)
    args.rig = str(_toml(tmp_path, "cells = [4, 4]\n"))
    scene, plan = ecli._prepare(args)
    assert scene == load_scene("sheet_4x4_rig") and plan.cells == list(range(1, 17))
    args = ecli.parser().parse_args(
        ["run", "sheet_8x8", "--channel", "x", "--rig", str(_toml(tmp_path, "cells = [8, 8]\n", "r64.toml"))]
    )
    scene, plan = ecli._prepare(args)
    assert scene.params.shape == (8, 8) and plan.cells == list(range(1, 65))
