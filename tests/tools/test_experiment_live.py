"""metacell_tools.experiment's live view beside the data path: a rehearsal with a deliberately slow renderer still
pushes on time and records when the push was sent, acknowledged and seen; the renderer drops drawings, never rows."""

import json

import numpy as np
import pytest

from host_emulator.workbench.trackers import PlotTracker
from metacell_tools.experiment import cli
from metacell_tools.experiment.runner import Repeat
from metacell_tools.experiment.summary import MOVE_COUNTS, repeat_result
from metacell_tools.rigtools.logger import SampleDecoder

SLOW_S = 2.0  # each drawing of the slow renderer takes this long


@pytest.fixture
def slow_renderer(monkeypatch):
    """Every drawing of the live plot takes SLOW_S more: in the renderer process (its test point) and in this one
    (where a renderer drawing in the receive loop would be as slow)."""
    import time

    monkeypatch.setenv("MC_LIVE_DRAW_DELAY_S", str(SLOW_S))
    draw = PlotTracker.update

    def slow(self):
        draw(self)
        time.sleep(SLOW_S)

    monkeypatch.setattr(PlotTracker, "update", slow)


def first_move(npz, cell: int, after_s: float) -> float:
    """Independent of the summary: the first sample (primary clock, from the enable) of the cell's alpha at least
    MOVE_COUNTS counts from its last sample at or before after_s, read from the repeat's NPZ capture."""
    z = np.load(npz, allow_pickle=True)
    attrs = json.loads(str(z["attrs"]))
    t = z["sample_time"][:, cell - 1] + attrs["t_origin_s"] - attrs["t_enable_primary_s"]  # primary clock - enable
    c = z["alpha_counts"][:, cell - 1]
    ok = np.isfinite(t) & np.isfinite(c)
    t, c = t[ok], c[ok]
    base = c[t <= after_s][-1]
    return float(t[(t > after_s) & (np.abs(c - base) >= MOVE_COUNTS)][0])


def test_live_rehearsal_with_a_slow_renderer_pushes_on_time(slow_renderer, tmp_path, capsys):
    out = tmp_path / "r"
    rc = cli.main(
        ["rehearse", "default", "--set", "t_end_s=1", "--timeout", "3", "--live", "50", "--out", str(out), "--no-plots"]
    )
    captured = capsys.readouterr()
    s = json.loads((out / "summary.json").read_text())
    (p,) = s["per_repeat"][0]["perturbations"]
    moved = first_move(out / "repeat_01.npz", 8, p["sent_s"])
    # the push left when the laptop said it did: alpha_8 moves a few poll cycles after the recorded send (the
    # command waits for cell 8's turn in the poll cycle, the torque takes a cycle to show as 2 counts: 15-45 ms
    # measured, the most on a loaded machine); a redraw in the receive loop held the frames back for a whole drawing
    # and the push went out about SLOW_S late (3.3 s before this test's fix, with 1 s drawings)
    assert 0 < moved - p["sent_s"] < 0.3, (p, moved)
    assert rc in (0, cli.EXIT_PROBLEMS) and s["failed_commands"] == [], captured.err
    assert p["cell"] == 8 and p["chain"] == "alpha" and p["result"] == "OK"
    cycle = s["per_repeat"][0]["poll_cycle_s"]
    assert 0.005 < cycle < 0.02  # 16 cells at 400 kHz: about 9 ms
    # the summary's record of it: when the firmware acknowledged it and when the plant showed it, on the primary's
    # clock; the cell moves within one poll cycle of the acknowledgement (plus one cell's slot in the cycle: the
    # result is dated by the newest sample before it, which may be the previous cell's)
    assert p["moved_s"] == pytest.approx(moved, abs=1e-9)
    assert p["sent_s"] < p["acked_s"] <= p["moved_s"] + 1e-9
    assert p["moved_s"] - p["acked_s"] <= cycle * (1 + 1 / 16), p
    assert p["ack_after_send_s"] == pytest.approx(p["acked_s"] - p["sent_s"])
    assert s["late_pushes"] == int(p["late"])  # late: more than 4 poll cycles, which a loaded machine can reach
    assert "push alpha_8 +20.0 mN*m for 0.1 s (repeat 1): planned 0.100 s, sent" in captured.out
    # the slow renderer still drew, into OUT/live.png
    assert (out / "live.png").stat().st_size > 5000


def test_a_late_push_is_flagged():
    """A CMD_RESULT that came many poll cycles after the recorded send: the laptop was behind, the record says so."""
    dec = SampleDecoder(n_cells=2, report=lambda t: None)
    for k in range(100):
        a = 0 if k < 60 else 3 * (k - 59)  # cell 1 moves from cycle 60
        for j in (1, 2):
            dec.sample(j, k % 256, a if j == 1 else 0, 0, k * 70 + j, 1, 1000.0)
    cyc = 70 * 128e-6
    push = {"label": "alpha_1", "cell": 1, "chain": "alpha", "planned_s": 0.1, "sent_s": 10 * cyc, "result": "OK"}
    rep = Repeat(1, dec, t0=0.0, t_stop=99 * cyc, stopped="t_end", perturbations=[dict(push, acked_s=59.5 * cyc)])
    rec, _ = repeat_result(rep, 2)
    (p,) = rec["perturbations"]
    assert rec["poll_cycle_s"] == pytest.approx(cyc)
    assert p["moved_s"] == pytest.approx(60 * cyc) and p["late"]  # t_s counts from cell 1's first sample
    assert p["ack_after_send_s"] == pytest.approx(49.5 * cyc) and p["move_after_ack_s"] == pytest.approx(0.5 * cyc)
    rep = Repeat(1, dec, t0=0.0, t_stop=99 * cyc, stopped="t_end", perturbations=[dict(push, acked_s=11.5 * cyc)])
    assert not repeat_result(rep, 2)[0]["perturbations"][0]["late"]


def test_the_renderer_drops_drawings_not_rows(monkeypatch):
    """Rows handed to a renderer that is still drawing wait and go together: it draws fewer times than it was fed,
    and its window ends up holding every row."""
    from metacell_tools.experiment.liveview import LiveView

    monkeypatch.setenv("MC_LIVE_DRAW_DELAY_S", "2")
    view = LiveView(10.0, 100.0)
    try:
        view.title = "t"
        view.setup(3, 5.0)
        assert view.wait_started() and view.interactive is False
        t = np.arange(300) * 0.01
        for k in range(0, 300, 10):  # 30 feeds of 10 rows, each worth a drawing (10 ms apart)
            view.sample_many(t[k : k + 10], np.ones((10, 3)) * k, np.zeros((10, 3)))
        view.update()
        view.close()
        assert view.wait(60) == 0
    finally:
        view.terminate()
    assert view.error is None
    assert view.rows == 300 and view.last_t == pytest.approx(2.99)
    assert 1 <= view.draws < 30 and view.batches < 30


def test_a_sheet_rigs_renderer_draws_the_current_field():
    """The renderer process of a sheet rig (RigLive's shape through LiveView's set-up message) draws the field: its
    hello line comes after a set-up that names the shape, and a wrong shape is said in one line."""
    from metacell_tools.experiment.liveview import LiveView

    view = LiveView(10.0, 100.0)
    try:
        view.title = "sheet"
        view.setup(16, 1.0, (4, 4))
        assert view.wait_started()
        view.sample_many(np.array([0.0, 0.1]), np.tile(np.arange(16.0), (2, 1)), np.zeros((2, 16)))
        view.update()
        view.close()
        assert view.wait(60) == 0
    finally:
        view.terminate()
    assert view.error is None and view.rows == 2
