"""metacell_tools.experiment's data path from decoded frames, no bus: the time series on the primary clock (held and
missing cells), the gap accounting of a repeat's summary, and the live plot fed from the logged frames."""

import numpy as np
import pytest

from host_emulator.workbench.trackers import PlotTracker
from metacell_tools.experiment.live import RigLive
from metacell_tools.experiment.runner import Repeat, series, tail_arrays
from metacell_tools.experiment.summary import repeat_result
from metacell_tools.rigtools.logger import RAD_PER_COUNT, SampleDecoder


def test_series_on_the_primary_clock_holds_and_flags_missing_cells():
    dec = SampleDecoder(n_cells=4, report=lambda t: None)
    truth = {}
    for k in range(20):
        t128 = k * 78  # 9.984 ms per cycle on the primary clock
        for j in (1, 2, 4):  # cell 3 never answers
            if j == 2 and k == 7:  # one lost sample
                continue
            a = k * j
            truth[(k, j)] = a
            dec.sample(j, k % 256, a, -a, t128 + j, 1, 1000.0 + 0.5 * k)  # host clock: irrelevant
    t0 = 5 * 78 * 128e-6
    s = series(dec.arrays(), t0, 0.0)
    # row time: mean primary clock of the row's samples minus t0 (cell offsets (j - 1) * 128 us: mean of 0, 1, 3)
    assert s.t[0] == pytest.approx(4 / 3 * 128e-6, abs=1e-9)  # t_s counts from the first sample (cell 1)
    assert s.t.size == 15 and np.all(np.diff(s.t) > 0)
    assert list(s.present) == [True, True, False, True]
    assert s.held[1] == 1 and s.held[0] == 0
    k7 = 2  # cycle 7 is row 2 after t0 (cycle 5)
    assert s.alpha[k7, 1] == pytest.approx(truth[(6, 2)] * RAD_PER_COUNT)  # held from cycle 6
    assert s.alpha[-1, 3] == pytest.approx(19 * 4 * RAD_PER_COUNT)
    assert np.all(np.isfinite(s.alpha)) and np.all(s.alpha[:, 2] == 0)
    assert series(dec.arrays(), t0, 0.0, 0.02).t[-1] <= 0.02
    # the live checks see only the tail of the run, on the same clock
    tail = series(tail_arrays(dec, 0.05), t0, 0.0)
    assert tail.t.size == 6 and tail.t[-1] == s.t[-1]


def test_summary_counts_sequence_gaps(tmp_path):
    dec = SampleDecoder(n_cells=16, report=lambda t: None)
    for k in range(40):
        for j in range(1, 17):
            if j == 9 and k in (10, 11, 12):
                continue  # three polls of cell 9 lost
            dec.sample(j, k % 256, 0, 0, k * 70, 1, 500.0 + k * 70 * 128e-6)
    rep = Repeat(1, dec, t0=0.0, t_stop=1.0, stopped="t_end")
    rec, s = repeat_result(rep, 16)
    assert rec["gaps"] == [{"cell": 9, "after_cycle": 9, "lost": 3}] and rec["samples_lost"] == 3
    assert rec["missing_cells"] == [] and rec["samples_per_cell"][8] == 37
    assert rec["samples_held"][8] == 3 and rec["steady"] is True


def test_rig_live_plot_draws_the_series_of_the_logged_frames():
    """RigLive polled as the runner polls it: the tracker ends up holding the same time series as the summary's."""
    from matplotlib.figure import Figure

    dec = SampleDecoder(n_cells=3, report=lambda t: None)
    tr = PlotTracker(interval_ms=50, window_s=10.0, fig=Figure())
    live = RigLive(tr, 3, title="x")
    live.begin(1, 5.0)
    t0 = 3 * 78 * 128e-6
    assert live.poll(dec, t0) == 0  # nothing logged yet
    fed = []
    for k in range(120):
        for j in (1, 2, 3):
            dec.sample(j, k % 256, 10 * j + k, -k, k * 78 + j, 1, 1000.0)
        fed.append(live.poll(dec, t0))
    live.finish(dec, t0)
    want = series(dec.arrays(), t0, 0.0)
    tw, aw, bw = tr.window()
    np.testing.assert_allclose(tw, want.t)
    np.testing.assert_array_equal(aw, want.alpha)
    np.testing.assert_array_equal(np.asarray(tr.image.get_array()), want.alpha)
    np.testing.assert_array_equal(bw, want.beta)
    # fed in steps of about one interval (78 * 128 us = 10 ms per cycle: every 5th cycle), not every row
    assert 15 <= sum(1 for n in fed if n) <= 30 and tr.title == "x (rig), repeat 1"
