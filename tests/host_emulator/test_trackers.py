"""Trackers and controller: every sample reaches every tracker once, in time order; bad t_end is refused."""

import io

import numpy as np
import pytest

from host_emulator.controller import run_solver
from host_emulator.models import ModelOptions, make_model
from host_emulator.params import Params
from host_emulator.trackers import LiveTracker, ProgressTracker, Tracker


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
