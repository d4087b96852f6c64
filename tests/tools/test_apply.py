"""`command apply DESIGN`: every cell's own reaction parameters written and read back, all or nothing; against the
emulated primary (`serve`) and against a model of the cells' register checks."""

import json

import pytest

from metacell_tools.experiment.rehearse import Serve
from metacell_tools.rigtools import command
from metacell_tools.rigtools.command import ApplyError, RigClient, apply_design, design_registers, read_params

SIGMA = [round(0.04 + 0.004 * j, 6) for j in range(16)]
K2 = [-0.06] * 8 + [-0.03] * 8


def _design(tmp_path, **params):
    d = {"cells": 16, "params": {"k_ab": 0.02, "sigma": SIGMA, "k1": 0.06, "k2": K2, "alpha_star": 1.1}}
    d["params"].update(params)
    f = tmp_path / "design.json"
    f.write_text(json.dumps(d))
    return f


def test_design_registers_are_the_wire_values_per_cell(tmp_path):
    want = design_registers(str(_design(tmp_path)))
    assert [want[j]["SIGMA"] for j in range(1, 17)] == [round(v * 1e6) for v in SIGMA]
    assert want[9]["K2"] == -30000 and want[1]["K2"] == -60000 and want[16]["ASTAR"] == 1100000
    assert design_registers(str(tmp_path)) == want  # the design's directory


@pytest.mark.parametrize(
    "params, words",
    [
        ({"sigma": SIGMA[:4] + [0.3] + SIGMA[5:]}, ["params.sigma[5] (cell 5)", "0.25"]),
        ({"k1": [0.06] * 11 + [-0.01] + [0.06] * 4}, ["cell 12", "k1 > max(k2, 0)"]),
        ({"sigma": SIGMA[:3]}, ["params.sigma", "3 values for 16 cells"]),
    ],
)
def test_a_value_a_cell_would_refuse_is_a_one_line_error_before_sending(tmp_path, params, words, capsys):
    f = _design(tmp_path, **params)
    with pytest.raises(ApplyError) as e:
        design_registers(str(f))
    assert all(w in str(e.value) for w in words) and "\n" not in str(e.value)
    # the command line: exit 2, and it never opens the port
    assert command.main(["-c", "/nonexistent@115200", "apply", str(f)]) == 2
    assert "error:" in capsys.readouterr().err


class Cells:
    """RigClient stand-in holding raw registers with the firmware's acceptance (k1 > max(k2, 0)); `reject`: a cell
    that answers RANGE to a register whatever the value (a cell with other limits)."""

    def __init__(self, reject=None):
        boot = {"K_AB": 20000, "SIGMA": 72000, "K1": 60000, "K2": -60000, "ASTAR": 1178097}
        self.reg = {j: dict(boot) for j in range(1, 17)}
        self.reject = reject
        self.sent = []

    def command(self, cells, reg, **values):
        out = {}
        for j in cells:
            self.sent.append((j, reg, values["value"]))
            if self.reject == (j, reg):
                out[j] = "RANGE"
                continue
            trial = dict(self.reg[j], **{reg: values["value"]})
            if trial["K1"] <= max(trial["K2"], 0):
                out[j] = "SHAPE"
                continue
            self.reg[j] = trial
            out[j] = "OK"
        return out

    def info(self, cells, blocks=()):
        f = command.PARAM_FIELDS
        return {j: {"PARAMS": {f[r]: v for r, v in self.reg[j].items()}} for j in cells}


def test_k1_and_k2_are_written_in_an_order_the_cells_accept(tmp_path):
    cells = Cells()
    cells.reg[3].update(K1=200000, K2=150000)  # left by an earlier experiment with k2 > 0
    want = design_registers(str(_design(tmp_path, k1=0.1, k2=-0.06)))  # cell 3's new k1 is below its old k2
    assert apply_design(cells, want, report=lambda s: None)
    assert all(cells.reg[j] == want[j] for j in range(1, 17))
    order = {j: [r for k, r, _ in cells.sent if k == j and r in ("K1", "K2")] for j in (1, 3)}
    assert order == {1: ["K1", "K2"], 3: ["K2", "K1"]}


def test_a_cell_rejecting_a_value_leaves_every_cell_as_it_was(tmp_path):
    cells = Cells(reject=(9, "SIGMA"))
    before = {j: dict(v) for j, v in cells.reg.items()}
    lines = []
    assert not apply_design(cells, design_registers(str(_design(tmp_path))), report=lines.append)
    assert cells.reg == before
    assert any("cell 9 answered RANGE to SIGMA" in s for s in lines)
    assert not any(j > 9 for j, _, _ in cells.sent)  # nothing sent past the refusing cell


@pytest.fixture(scope="module")
def served():
    with Serve("default", ["t_end_s=600"], ["--absent", "7"], duration_s=600) as srv:
        yield srv


def _bus(channel):
    from metacell_tools.rigtools.slcanbus import open_bus

    return open_bus("slcan", channel, 0.1)


def test_per_cell_parameters_round_trip_through_the_command_tool_against_serve(served, tmp_path, capsys):
    f = _design(tmp_path, k_ab=[0.02] * 6 + [0.03] * 10)
    want = design_registers(str(f))
    want.pop(7)
    # cell 7 is absent: refused, nothing written
    assert command.main(["-c", served.channel, "apply", str(f)]) == 1
    assert "did not report" in capsys.readouterr().out
    with _bus(served.channel) as bus:
        before = read_params(RigClient(bus), [1, 8, 16])
    assert before[8]["SIGMA"] == 72000 and before[16]["K2"] == -60000
    # the other cells: written and read back, each its own values
    d = json.loads(f.read_text())
    d["cells"] = 6
    for k, v in d["params"].items():
        if isinstance(v, list):
            d["params"][k] = v[:6]
    f6 = tmp_path / "six.json"
    f6.write_text(json.dumps(d))
    assert command.main(["-c", served.channel, "apply", str(f6)]) == 0
    out = capsys.readouterr().out
    assert "every cell holds its parameters" in out and out.count("written and read back") == 6
    with _bus(served.channel) as bus:
        got = read_params(RigClient(bus), list(range(1, 7)))
    for j in range(1, 7):
        assert got[j] == want[j]
    assert got[6]["SIGMA"] == round(SIGMA[5] * 1e6) != got[1]["SIGMA"]


def _six(tmp_path, name, **firmware):
    """A six-cell design.json (cell 7 is absent from `served`) assuming this firmware configuration."""
    fw = {"bemf_comp": False, "pwm_limit_ticks": 5860 * 2400 // 9000, "pwm_top": 2400, **firmware}
    d = {"cells": 6, "params": {"k_ab": 0.021, "sigma": SIGMA[:6], "k1": 0.06, "k2": -0.05, "alpha_star": 1.1}}
    d["assumes"] = {"firmware": fw}
    f = tmp_path / name
    f.write_text(json.dumps(d))
    return f


def test_apply_refuses_a_design_assuming_another_configuration_and_sets_it_when_asked(served, tmp_path, capsys):
    cells = list(range(1, 7))
    with _bus(served.channel) as bus:
        before = read_params(RigClient(bus), cells)
        conf = command.read_config(RigClient(bus), cells)
    assert all(c == {"bemf": 0, "pwm_limit": 5860 * 2400 // 9000} for c in conf.values())
    on = _six(tmp_path, "on.json", bemf_comp=True)
    assert command.design_config(str(on)) == {"bemf": 1, "pwm_limit": 1562}
    # the rig runs without back-EMF compensation, the design assumes it: refused, nothing written
    assert command.main(["-c", served.channel, "apply", str(on)]) == 1
    out = capsys.readouterr().out
    assert "back-EMF compensation off" in out and "refused" in out and "NOT applied" in out
    with _bus(served.channel) as bus:
        assert read_params(RigClient(bus), cells) == before
        assert command.read_config(RigClient(bus), cells) == conf
    # --configure: the cells get the design's configuration, then its parameters
    assert command.main(["-c", served.channel, "apply", str(on), "--configure"]) == 0
    assert "configured 6 cell(s)" in capsys.readouterr().out
    with _bus(served.channel) as bus:
        assert all(c == {"bemf": 1, "pwm_limit": 1562} for c in command.read_config(RigClient(bus), cells).values())
        assert read_params(RigClient(bus), [3])[3]["SIGMA"] == round(SIGMA[2] * 1e6)
    # a design assuming the configuration in force: applied without --configure; then back as `served` started
    half = _six(tmp_path, "half.json", bemf_comp=True, pwm_limit_ticks=1000)
    assert command.main(["-c", served.channel, "apply", str(half)]) == 1
    capsys.readouterr()
    assert command.main(["-c", served.channel, "apply", str(_six(tmp_path, "again.json", bemf_comp=True))]) == 0
    assert command.main(["-c", served.channel, "apply", str(_six(tmp_path, "off.json")), "--configure"]) == 0
    with _bus(served.channel) as bus:
        assert command.read_config(RigClient(bus), cells) == conf


def test_a_design_whose_configuration_is_unreadable_is_a_one_line_error(tmp_path, capsys):
    d = json.loads(_six(tmp_path, "bad.json").read_text())
    del d["assumes"]["firmware"]["pwm_limit_ticks"]
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(ApplyError):
        command.design_config(str(tmp_path / "bad.json"))
    assert command.main(["-c", "/nonexistent@115200", "apply", str(tmp_path / "bad.json")]) == 2
    err = capsys.readouterr().err
    assert "firmware configuration is unreadable" in err and err.count("\n") == 1
    assert command.design_config(str(_design(tmp_path))) is None  # written before designs recorded it: no check
