"""benchmarks/continuum2d: the sheet case, the cell sampling it compares on, and its ratio line (no py-pde run:
its numba compilation alone takes tens of seconds)."""

import numpy as np

from host_emulator.benchmarks import continuum2d as c2


def test_case_is_the_same_noise_on_every_volume_of_a_cell():
    p, a0 = c2.case(4, 2)
    assert p.topology.is_sheet and p.topology.periodic and p.cells == 16 and a0.shape == (8, 8)
    assert np.array_equal(a0[::2, ::2], a0[1::2, 1::2]) and np.abs(a0).max() <= 0.05
    assert np.array_equal(c2.cells_of(a0, 2), a0[::2, ::2].ravel())  # the mean of a cell's 4 equal volumes


def test_ours_agrees_with_bdf_on_a_small_sheet(monkeypatch):
    monkeypatch.setattr(c2, "T_END", 0.05)
    ref = c2.run_ours(6, 1, 1e-9)
    loose = c2.run_ours(6, 1, 1e-4)
    bdf = c2.run_ours(6, 1, 1e-9, method="BDF")
    assert ref.shape == (2, 36)
    assert c2.err(bdf, ref) < 1e-6 and c2.err(loose, ref) < 1e-2 and np.abs(ref).max() > 0.005


def test_ratio_line_picks_the_fastest_row_under_the_error():
    rows = [
        ("ours ETDRK4", "rtol=1e-3", 1.0, 2e-3),
        ("ours ETDRK4", "rtol=1e-4", 2.0, 5e-5),
        ("py-pde euler", "dt=1e-4", 3.0, 8e-4),
        ("py-pde runge-kutta", "tol=1e-6", 20.0, 1e-6),
    ]
    assert "= 1.5x" in c2.ratio_line(rows, 1e-3)
    assert "= 10.0x" in c2.ratio_line(rows, 1e-4)
    assert "not reached" in c2.ratio_line(rows[:2], 1e-3)
