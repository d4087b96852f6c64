"""Trackers and controller: every sample reaches every tracker once, in time order; bad t_end is refused."""

import io

import numpy as np
import pytest

from host_emulator.controller import run_solver
from host_emulator.models import ModelOptions, make_model
from host_emulator.params import Params
from host_emulator.workbench.trackers import LiveTracker, ProgressTracker, Tracker


class Count(Tracker):
    def start(self, solver, t_end_s, n):
        self.t, self.n, self.done = [], n, False

    def sample(self, t, a, b):
        self.t.append(t)

    def finish(self):
        self.done = True


def test_trackers_see_every_sample():
    m = make_model("lattice", Params(cells=4), [], ModelOptions(dt_out=0.05))
    c, buf = Count(), io.StringIO()
    res = run_solver(m.solver(), 1.0, [c, LiveTracker(0.5, file=buf), ProgressTracker(file=io.StringIO())])
    assert c.done and len(c.t) == c.n == 21 and np.all(np.diff(c.t) > 0)
    np.testing.assert_allclose(res.t, c.t)
    assert buf.getvalue().count("max|alpha|") == 3  # t = 0, 0.5, 1.0


def test_bad_t_end():
    m = make_model("lattice", Params(cells=4), [], ModelOptions())
    with pytest.raises(ValueError, match="t_end_s"):
        run_solver(m.solver(), float("nan"))


# ---- live plot -------------------------------------------------------------------------------------------
def _plot_tracker(**kw):
    from matplotlib.figure import Figure

    from host_emulator.workbench.trackers import PlotTracker

    return PlotTracker(fig=Figure(), **kw)


def test_plot_tracker_draws_the_recorded_run():
    """Through the controller: the map is the recorded alpha (window longer than the run), the profile its last row."""
    import matplotlib

    assert matplotlib.get_backend().lower() == "agg"  # the test environment's choice (conftest), not the package's
    from host_emulator.controller import run_scene
    from host_emulator.scene import load_scene

    p = _plot_tracker(interval_ms=100, window_s=5.0)
    res = run_scene(load_scene("default", ["model=lattice", "t_end_s=1"]), progress=False, trackers=[p])
    assert np.abs(res.alpha).max() > 0.1  # the pattern grew: there is something to draw
    np.testing.assert_array_equal(np.asarray(p.image.get_array()), res.alpha)
    np.testing.assert_array_equal(p.line_a.get_ydata(), res.alpha[-1])
    np.testing.assert_array_equal(p.line_b.get_ydata(), res.beta[-1])
    assert p.image.get_extent()[2:] == [0.0, pytest.approx(res.t[-1])]
    lo, hi = p.image.get_clim()
    assert hi == -lo == pytest.approx(np.abs(res.alpha).max())
    # at most one redraw per 100 ms of simulated time (t = 0, 0.1, ..., 1.0) and the final one; a compiled chunk
    # that spans several intervals is drawn once
    assert 2 <= p.draws <= 12


def test_plot_tracker_window_rolls():
    """Fed in uneven chunks, the map keeps exactly the samples of the last window_s, oldest first."""
    rng = np.random.default_rng(3)
    t = np.arange(500) * 0.01
    a, b = rng.normal(size=(500, 5)), rng.normal(size=(500, 5))
    p = _plot_tracker(interval_ms=50, window_s=1.0)
    p.setup(5)
    cuts = [0, 3, 40, 41, 200, 333, 500]
    for i, j in zip(cuts[:-1], cuts[1:]):
        p.sample_many(t[i:j], a[i:j], b[i:j])
    p.update()
    keep = t >= t[-1] - 1.0 - 1e-12
    np.testing.assert_array_equal(np.asarray(p.image.get_array()), a[keep])
    tw, aw, bw = p.window()
    np.testing.assert_array_equal(tw, t[keep])
    np.testing.assert_array_equal(bw, b[keep])
    # one sample at a time: a redraw whenever 50 ms passed since the last one
    q = _plot_tracker(interval_ms=50, window_s=1.0)
    q.setup(5)
    for k in range(101):
        q.sample(t[k], a[k], b[k])
    assert q.draws == 21  # t = 0, 0.05, ..., 1.0
    np.testing.assert_array_equal(q.line_a.get_ydata(), a[100])


def test_plot_tracker_refuses_bad_settings():
    from host_emulator.workbench.trackers import PlotTracker

    for kw in ({"interval_ms": 0}, {"window_s": -1}, {"interval_ms": float("nan")}):
        with pytest.raises(ValueError, match="PlotTracker"):
            PlotTracker(**kw)


def test_cli_live_writes_the_figure_on_a_headless_backend(tmp_path, capsys):
    """`run SCENE --live` under Agg: no window can open, so OUT/live.png is rewritten and the user is told."""
    from host_emulator import cli

    out = tmp_path / "r"
    rc = cli.main(["run", "default", "--set", "t_end_s=0.3", "--live", "100", "--out", str(out), "--no-plots"])
    assert rc == 0
    assert "live.png is rewritten every 100 ms" in capsys.readouterr().err
    assert (out / "live.png").stat().st_size > 5000
    with pytest.raises(SystemExit):
        cli.main(["run", "default", "--live", "-5"])


def test_plot_tracker_draws_a_sheet_field_in_row_major_order():
    """On a sheet the right panel is the newest alpha as (rows, cols): cell (row, col) is cell (row - 1) * cols + col,
    whether the tracker is set up by a solver (the topology's shape) or by a feed (the rig's live view)."""
    from matplotlib.figure import Figure

    from host_emulator.models.options import Perturbation
    from host_emulator.workbench.trackers import PlotTracker

    p = Params(cells=12, shape=(3, 4), lattice="square")
    push = [Perturbation(cell=p.topology.cell_of(2, 3), chain=0, torque_Nm=0.01, start_s=0.0, duration_s=0.05)]
    tr = PlotTracker(20.0, 1.0, fig=Figure())
    res = run_solver(make_model("lattice", p, push, ModelOptions(dt_out=0.005)).solver(), 0.01, [tr])
    assert tr.shape == (3, 4) and tr.field is not None
    field = np.asarray(tr.field.get_array())
    np.testing.assert_array_equal(field, res.alpha[-1].reshape(3, 4))
    # 10 ms into the push the pushed cell (2, 3) has turned most (later the whole small sheet follows it)
    assert np.unravel_index(np.argmax(np.abs(field)), field.shape) == (1, 2)

    feed = PlotTracker(10.0, 1.0, fig=Figure())
    feed.setup(6, 1.0, (2, 3))
    feed.sample_many(np.array([0.0, 0.5]), np.array([np.zeros(6), np.arange(6.0)]), np.zeros((2, 6)))
    feed.update()
    np.testing.assert_array_equal(np.asarray(feed.field.get_array()), [[0, 1, 2], [3, 4, 5]])
    chain = PlotTracker(10.0, 1.0, fig=Figure())
    chain.setup(6, 1.0)
    assert chain.field is None and chain.line_a is not None
    with pytest.raises(ValueError, match="does not hold 6 cells"):
        PlotTracker(10.0, 1.0, fig=Figure()).setup(6, 1.0, (2, 4))
