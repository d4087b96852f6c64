"""The researcher's round trip: every way the project writes a run (the emulator, a rehearsal, the rigtools logger,
python-can's own can.logger on `serve`) opens with host_emulator.load into one dataset layout, any two of them
overlay with `experiment compare`, and no writer labels a rehearsal (or any emulated run) `rig`."""

import json
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import host_emulator as he
from host_emulator.cli import main as emulator_main
from host_emulator.workbench.datasets import FORMAT
from metacell_tools.experiment import cli
from metacell_tools.experiment.rehearse import Serve
from metacell_tools.rigtools import proto
from tests.conftest import ctrl_c_default

ROOT = proto.ROOT
RX_TIME = re.compile(r"^\s*(\d+\.\d+)\s+\d+\s+\S+\s+Rx\b", re.M)  # an ASC frame line
RIG = re.compile(r"\brig\b")  # the label itself; "rig k" (the band stiffness) never appears in these outputs


@pytest.fixture(scope="module")
def served():
    """`serve exp1_ccw_ccw` as a user starts it: the scene's own pushes, so a capture sees a pattern."""
    with Serve("exp1_ccw_ccw", [], duration_s=300) as srv:
        yield srv


@pytest.fixture(scope="module")
def outputs(tmp_path_factory, served):
    """Write one run of each kind (module scope: the slow part runs once), recording every figure's text."""
    from matplotlib.figure import Figure

    d = tmp_path_factory.mktemp("rt")
    texts: dict[str, list[str]] = {}
    real_savefig = Figure.savefig

    def savefig(self, fname, *a, **kw):
        texts[str(fname)] = [t.get_text() for t in self.findobj(lambda o: hasattr(o, "get_text"))]
        return real_savefig(self, fname, *a, **kw)

    Figure.savefig = savefig
    try:
        # python-can's own logger on the emulated primary
        asc = d / "can.asc"
        lg = subprocess.Popen(
            [sys.executable, "-m", "can.logger", "-i", "slcan", "-c", served.channel, "-f", str(asc)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            preexec_fn=ctrl_c_default,  # a suite run in the background would pass SIGINT on ignored
        )
        # 4 s of frames by the log's own timestamps, not from the start (a loaded machine starts python-can slowly)
        end = time.monotonic() + 300
        while time.monotonic() < end and lg.poll() is None:
            ts = [float(m) for m in RX_TIME.findall(asc.read_text(errors="replace"))] if asc.exists() else []
            if ts and ts[-1] - ts[0] >= 4.0:
                break
            time.sleep(0.5)
        lg.send_signal(signal.SIGINT)
        lg.communicate(timeout=300)
        # the rigtools logger on the same primary (the channel is a pty: it labels the capture emulator:hil)
        r = subprocess.run(
            [sys.executable, "-m", "metacell_tools.rigtools.logger", "-c", served.channel, "-o", str(d / "cap")]
            + ["--duration", "2"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 0, r.stderr
        # a rehearsal (its own server) and the emulator run of the same scene
        rc = cli.main(["rehearse", "exp1_ccw_ccw", "--set", "t_end_s=2", "--timeout", "3", "--out", str(d / "reh")])
        assert rc in (cli.EXIT_OK, cli.EXIT_PROBLEMS)
        assert emulator_main(["run", "exp1_ccw_ccw", "--set", "t_end_s=2", "--out", str(d / "emu"), "--quiet"]) == 0
        # `run` pointed at the emulator's pty is not the rig either
        rc = cli.main(
            ["run", "exp1_ccw_ccw", "-c", served.channel, "--set", "t_end_s=1", "--timeout", "3"]
            + ["--open-wait", "0.1", "--out", str(d / "run_on_pty"), "--repeats", "1"]
        )
        assert rc in (cli.EXIT_OK, cli.EXIT_PROBLEMS)
        assert cli.main(["compare", str(d / "reh"), str(d / "emu"), "--out", str(d / "c1.png")]) == 0
        assert cli.main(["compare", str(asc), str(d / "emu"), "--out", str(d / "c2.png")]) == 0
    finally:
        Figure.savefig = real_savefig
    return d, texts


def test_every_kind_of_run_loads_into_one_layout(outputs):
    d, _ = outputs
    runs = {
        "emu": (d / "emu", "emulator:hil"),
        "reh": (d / "reh", "rehearsal:hil"),
        "cap_npz": (d / "cap.npz", "emulator:hil"),
        "cap_csv": (d / "cap.csv", "emulator:hil"),
        "asc": (d / "can.asc", "unknown"),
        "pty_run": (d / "run_on_pty", "rehearsal:hil"),
    }
    loaded = {}
    for name, (path, source) in runs.items():
        ds = he.load(path)
        loaded[name] = ds
        assert ds.attrs["format"] == FORMAT and ds.attrs["source"] == source, (name, ds.attrs.get("source"))
        assert ds["alpha"].dims == ("time", "cell") and ds["beta"].dims == ("time", "cell"), name
        assert list(ds["cell"].values) == list(range(1, 17)), name
        assert ds["alpha"].attrs["units"] == "rad" and ds["time"].attrs["units"] == "s", name
        t = ds["time"].values
        assert t.size > 20 and np.all(np.diff(t) > 0), name
        assert np.nanmax(np.abs(ds["alpha"].values)) > 0.3, name  # the pushes did move the lattice
    # a python-can log says nothing about its sender: the label is the caller's
    assert he.load(d / "can.asc", source="emulator:hil").attrs["source"] == "emulator:hil"
    # the logger's NPZ and its CSV are the same samples
    np.testing.assert_array_equal(loaded["cap_npz"]["alpha"].values, loaded["cap_csv"]["alpha"].values)
    # the rig captures carry the frames' flags and each cell's own primary clock
    for name in ("cap_npz", "asc", "reh"):
        assert {"flags", "sample_time", "alpha_counts"} <= set(loaded[name].data_vars) or name == "reh"
    # an emulator run: the same angles as its summary, and its scene's parameters
    s = json.loads((d / "emu" / "summary.json").read_text())
    np.testing.assert_allclose(loaded["emu"]["alpha"].values[-1], s["final_alpha_rad"])
    assert (
        loaded["emu"].attrs["params.sigma"] == pytest.approx(0.072) and loaded["emu"].attrs["scene"] == "exp1_ccw_ccw"
    )
    # a rehearsal: the drive-on series of its first repeat, and each repeat's raw capture from the drive enable
    r = json.loads((d / "reh" / "summary.json").read_text())
    np.testing.assert_allclose(loaded["reh"]["alpha"].values[-1], r["per_repeat"][0]["final_alpha_rad"])
    rep = he.load(d / "reh", repeat=1)
    assert rep.attrs["source"] == "rehearsal:hil" and rep.attrs["repeat"] == 1
    t = rep["time"].values
    assert t[0] < 0 < t[-1]  # setup before the enable (t < 0), the run after it
    # on the same clock as the summary's series: at its last time, the raw capture holds the same angles
    last = float(loaded["reh"]["time"].values[-1])
    k = int(np.argmin(np.abs(t - last)))
    assert abs(t[k] - last) < 0.02
    np.testing.assert_allclose(rep["alpha"].values[k], loaded["reh"]["alpha"].values[-1], atol=2 * 2 * np.pi / 400)


def test_compare_overlays_any_two(outputs):
    d, texts = outputs
    assert (d / "c1.png").stat().st_size > 5000 and (d / "c2.png").stat().st_size > 5000
    c2 = " ".join(texts[str(d / "c2.png")])
    assert "unknown (A)" in c2 and "emulator:hil (B)" in c2


def _strings(v):
    if isinstance(v, dict):
        for k, x in v.items():
            yield str(k)
            yield from _strings(x)
    elif isinstance(v, list):
        for x in v:
            yield from _strings(x)
    elif isinstance(v, str):
        yield v


def test_no_writer_labels_an_emulated_run_rig(outputs):
    """Every writer of every emulated run: summary.json (source, model, every string), the NPZ files' attributes
    and names, the log files' names, every figure's text (titles, legends, labels), the compare table."""
    d, texts = outputs
    for run in ("reh", "emu", "run_on_pty"):
        s = json.loads((d / run / "summary.json").read_text())
        assert s["source"] != "rig" and s["model"] != "rig", run
        for text in _strings({k: v for k, v in s.items() if k not in ("params", "model_options", "plan")}):
            assert not RIG.search(text) or text.startswith(str(d)), (run, text)
        for f in (d / run).iterdir():
            assert "rig" not in f.name, f
            if f.suffix == ".npz":
                with np.load(f) as z:
                    attrs = json.loads(str(z["attrs"]))
                assert attrs["source"] in ("rehearsal:hil", "emulator:hil"), (f, attrs["source"])
    for cap in ("cap.npz",):
        with np.load(d / cap) as z:
            assert json.loads(str(z["attrs"]))["source"] == "emulator:hil"
    drawn = {f: t for f, t in texts.items() if "/reh/" in f or "/emu/" in f or "/run_on_pty/" in f or "c1" in f}
    assert len(drawn) >= 7  # spacetime, final pattern, dispersion (x2 runs + the pty run) and the overlay
    for f, t in drawn.items():
        for text in t:
            assert not RIG.search(text), (f, text)
