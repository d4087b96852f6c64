"""Summaries that say where: the domain walls' bonds beside their count (summary.json, the dataset, the printout), and
an oscillation reported only when the end of the run still shows it (ringing after a push that dies out is none)."""

import json

import numpy as np
import pytest

from host_emulator.analysis.observables import domain_wall_bonds, domain_walls, observables
from host_emulator.cli import main


def _kinks(walls, n=16, width=0.6):
    """A profile of amplitude 0.6 rad whose sign flips at each wall (bond positions j + 0.5, cells j = 1..n)."""
    j = np.arange(1, n + 1, dtype=float)
    u = np.full(n, 0.6)
    for w in walls:
        u = u * np.tanh((w - j) / width)
    return u


@pytest.mark.parametrize("walls", [[4.5, 10.5], [2.5, 6.5, 10.5, 14.5], [7.5], []])
def test_wall_bonds_are_where_the_profile_changes_sign(walls):
    u = _kinks(walls)
    assert domain_wall_bonds(u) == walls
    assert len(domain_wall_bonds(u)) == domain_walls(u)
    o = observables(np.linspace(0, 1, 11), np.tile(u, (11, 1)), np.zeros((11, 16)))
    assert o["domain_wall_bonds"] == walls and o["domain_walls"] == len(walls)


def test_a_cell_near_zero_inside_a_wall_puts_it_at_the_nearer_bond():
    u = np.array([0.6, 0.6, 0.6, 0.05, -0.5, -0.6])  # cell 4 below the 0.1 rad threshold: the wall spans 3..5
    # the straight line from +0.6 (cell 3) to -0.5 (cell 5) crosses zero at 3 + 2 * 0.6 / 1.1 = 4.09: bond 4.5
    assert domain_wall_bonds(u) == [4.5]
    u = np.array([0.6, 0.6, 0.2, 0.05, -0.6, -0.6])  # from +0.2 (cell 3) to -0.6 (cell 5): 3.5, bond 3.5
    assert domain_wall_bonds(u) == [3.5]


def test_design_reads_walls_as_the_summary_does():
    from host_emulator.workbench.design import final_walls

    u = _kinks([5.5, 10.5])
    assert final_walls(u) == domain_wall_bonds(u) == [5.5, 10.5]
    assert final_walls(u, rest=(16,)) == [5.5, 10.5]


def test_ringing_that_died_before_the_end_is_no_oscillation():
    """A pattern that rang at 0.0342 s after its push and is still for the last seconds: steady, no oscillation
    (before: steady True beside an oscillation period of 0.0342 s)."""
    t = np.arange(0, 10.0, 0.002)
    pattern = _kinks([7.5])
    ring = 0.3 * np.exp(-t / 0.4) * np.sin(2 * np.pi * t / 0.0342)
    alpha = pattern[None, :] * (1 - np.exp(-t / 0.05))[:, None] + ring[:, None] * np.linspace(1, -1, 16)[None, :]
    o = observables(t, alpha, np.zeros_like(alpha))
    assert o["steady"] is True
    assert o["oscillation_period_s"] is None


def test_an_oscillation_that_lasts_to_the_end_is_reported():
    t = np.arange(0, 3.0, 0.001)
    alpha = 0.4 * np.sin(2 * np.pi * t / 0.03)[:, None] * np.ones(16)[None, :]
    o = observables(t, alpha, 0.1 * alpha)
    assert o["steady"] is False
    assert o["oscillation_period_s"] == pytest.approx(0.03, rel=1e-3)


def test_summary_json_dataset_and_printout_give_the_walls_bonds(tmp_path, capsys):
    import host_emulator as he

    out = tmp_path / "r"
    assert main(["run", "default", "--out", str(out), "--quiet", "--no-plots"]) == 0
    printed = capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    bonds = s["domain_wall_bonds"]
    assert len(bonds) == s["domain_walls"] == 4
    # independent reading of the final profile: each wall lies between two cells of opposite sign (both above
    # the threshold, or with only sub-threshold cells between them)
    u = np.array(s["final_alpha_rad"])
    for b in bonds:
        lo, hi = int(b - 0.5), int(b + 0.5)  # cells j, j + 1 (1-based)
        left = [v for v in u[:lo][::-1] if abs(v) > 0.1][0]
        right = [v for v in u[hi - 1 :] if abs(v) > 0.1][0]
        assert np.sign(left) != np.sign(right), (b, u)
    assert f"domain walls: 4 at {', '.join(f'{b:g}' for b in bonds)}" in printed
    ds = he.load(out)
    np.testing.assert_array_equal(ds.attrs["observable.domain_wall_bonds"], bonds)
