"""Benchmark helpers: Pareto-front interpolation of wall time at a target error (property tests), table layout."""

import math

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from host_emulator.benchmarks.common import WPPoint, table, wall_at


def pts(pairs):
    return [WPPoint("m", "", w, e) for w, e in pairs]


def test_exact_power_law_is_interpolated_exactly():
    # error = 1e-2 * (w / 1e-3)^-2: at 1e-4 error, w = 1e-2
    P = [(w, 1e-2 * (w / 1e-3) ** -2) for w in (1e-3, 3e-3, 3e-2, 1e-1)]
    assert wall_at(pts(P), 1e-4) == pytest.approx(1e-2, rel=1e-12)


def test_unreached_target_and_dominated_points():
    assert wall_at(pts([(1.0, 1e-3), (2.0, 5e-4)]), 1e-4) is None
    # a slower, less accurate run (dominated) must not change the answer; failed runs (inf) are ignored
    base = [(1e-3, 1e-2), (1e-2, 1e-6)]
    assert wall_at(pts(base + [(5e-3, 1e-1), (1e-4, math.inf)]), 1e-4) == wall_at(pts(base), 1e-4)
    # the cheapest run already reaching the target is the answer
    assert wall_at(pts([(2e-3, 1e-5), (1e-2, 1e-7)]), 1e-4) == 2e-3


@given(st.lists(st.tuples(st.floats(1e-4, 10.0), st.floats(1e-9, 1.0)), min_size=1, max_size=12), st.floats(1e-9, 1.0))
@example([(1.0, 1.0000000000000003e-09), (2.0, 1e-09)], 1e-09)  # logs equal: was a ZeroDivisionError
def test_wall_at_is_bracketed_by_the_front(P, target):
    """The interpolated wall lies between the walls of the front points around the target, and no run that
    reaches the target is cheaper than the answer."""
    w = wall_at(pts(P), target)
    reach = [pw for pw, pe in P if pe <= target]
    if not reach:
        assert w is None
        return
    assert w is not None and w <= min(reach) * (1 + 1e-12)
    assert w >= min(pw for pw, _ in P) * (1 - 1e-12)


def test_table_aligns_columns():
    out = table([["a", 1], ["bbb", 22]], ["x", "y"]).splitlines()
    assert out[0].startswith("x  ") and out[1].startswith("---") and len({line.index("1") for line in out[2:3]}) == 1
    assert out[3].split() == ["bbb", "22"]
