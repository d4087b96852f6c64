"""metacell_tools.experiment's runner with no rig: setup order and SHAPE errors against a model of the cells' register
checks, and bad scene keys or options refused before the port is opened."""

from host_emulator.scene import load_scene
from metacell_tools.experiment import cli
from metacell_tools.experiment.plan import make_plan
from metacell_tools.experiment.runner import Experiment, Options


def test_bad_scene_key_fails_before_touching_the_rig(tmp_path, capsys):
    out = tmp_path / "b"
    rc = cli.main(
        ["run", "exp1_ccw_ccw", "--channel", "/nonexistent/port@115200", "--set", "params.bogus=1", "--out", str(out)]
    )
    assert rc == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "params.bogus" in err and "cannot open" not in err
    assert not out.exists()
    rc = cli.main(
        [
            "run",
            "exp1_ccw_ccw",
            "--channel",
            "/nonexistent/port@115200",
            "--set",
            "perturbation.1.torque_Nm=0.5",
            "--out",
            str(out),
        ]
    )
    assert rc == cli.EXIT_USAGE and "torque_Nm" in capsys.readouterr().err and not out.exists()


class FakeCells:
    """RigClient stand-in: per-cell parameters with the firmware's acceptance rule (k1 > max(k2, 0), |k| <= 0.25)."""

    def __init__(self, k1=60000, k2=-60000, absent=()):
        self.k = {j: {"K1": k1, "K2": k2} for j in range(1, 17)}
        self.absent = set(absent)
        self.log = []

    def command(self, cells, reg, **values):
        out = {}
        for j in cells:
            self.log.append((j, reg))
            if j in self.absent:
                out[j] = "NACK"
                continue
            if reg in ("K1", "K2"):
                trial = dict(self.k[j], **{reg: values["value"]})
                if trial["K1"] <= max(trial["K2"], 0):
                    out[j] = "SHAPE"
                    continue
                self.k[j] = trial
            out[j] = "OK"
        return out


class QuietBus:
    def recv(self, timeout=None):
        return None


def _experiment(tmp_path, scene_sets, cells, **opts):
    sc = load_scene("exp5_rest", scene_sets)
    exp = Experiment(QuietBus(), make_plan(sc), tmp_path, Options(**opts), report=lambda t: None)
    exp.client = cells
    return exp


def test_k1_below_the_old_k2_is_set_after_k2(tmp_path):
    cells = FakeCells(k1=80000, k2=40000)  # left by an earlier scene with k2 > 0
    exp = _experiment(tmp_path, ["params.k1=0.03", "params.k2=-0.06"], cells)
    ok = exp._setup("repeat 1")
    assert ok == list(range(1, 17)) and exp.failures == []
    assert all(cells.k[j] == {"K1": 30000, "K2": -60000} for j in range(1, 17))
    exp.finish()


def test_setup_reports_a_genuine_shape_error_and_the_failing_cells(tmp_path):
    cells = FakeCells(absent=[5])
    exp = _experiment(tmp_path, ["params.k1=0.01", "params.k2=0.02"], cells)  # k1 <= k2: no order helps
    ok = exp._setup("repeat 1")
    assert ok == []
    got = {(f["reg"], f["result"]) for f in exp.failures if f["cell"] != 5}
    assert got == {("K2", "SHAPE")}  # k1 = 0.01 is accepted against the old k2, k2 = 0.02 is not
    assert {f["result"] for f in exp.failures if f["cell"] == 5} == {"NACK"}
    exp.finish()


def test_bad_options_fail_before_touching_the_rig(tmp_path, capsys):
    out = tmp_path / "o"
    for args, word in (
        (["--formats", "asc,xyz"], "--formats"),
        (["--repeats", "0"], "--repeats"),
        (["--t-end", "-1"], "--t-end"),
        (["--settle", "0"], "--settle"),
    ):
        rc = cli.main(["run", "exp1_ccw_ccw", "--channel", "/nonexistent/port@115200", "--out", str(out), *args])
        err = capsys.readouterr().err
        assert rc == cli.EXIT_USAGE and word in err and "cannot open" not in err, (args, err)
    assert not out.exists()
