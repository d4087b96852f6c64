"""2-D pattern measures on hand-made fields: stripes, hexagonal and square spots, labyrinths, rest and oscillation."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis import pattern2d as p2
from host_emulator.analysis.observables import domain_walls
from host_emulator.benchmarks.pattern2d import dislocated, hex_spots, labyrinth, main, square_spots, stripes
from host_emulator.topology import Topology

OPEN16 = [Topology((16, 16), "square"), Topology((16, 16), "hex")]
PER32 = [Topology((32, 32), "square", True), Topology((32, 32), "hex", True)]


def still(u, samples=5):
    """A steady run ending in the frame u."""
    return np.linspace(0, 1, samples), np.tile(u, (samples, 1))


def measure(t, u):
    return p2.measures(*still(u), t)


def turn(a, b):
    """The angle between two orientations (degrees, modulo 180)."""
    d = (a - b) % 180
    return min(d, 180 - d)


# ---- stripes ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("t", OPEN16, ids=lambda t: t.kind)
@pytest.mark.parametrize(("lam", "deg"), [(8, 0), (8, 30), (6, 45), (5, 90), (4, 120), (10, 15), (7, 160)])
@pytest.mark.parametrize("sat", [False, True])
def test_stripes_on_an_open_16x16_sheet(t, lam, deg, sat):
    """The least-squares refinement finds a plane wave's wavevector exactly (1e-6 rad/cell); a saturated (tanh)
    profile's harmonics pull it by up to ~1 % on 16 cells (the chain's spatial_period allows 5 % for the same)."""
    m = measure(t, stripes(t, lam, deg, sat))
    assert m["pattern_kind"] == "stripes"
    assert m["dominant_wavelength_cells"] == pytest.approx(lam, rel=0.02 if sat else 1e-4)
    assert turn(m["orientation_deg"], deg) < (1.0 if sat else 0.01)
    assert 0 <= m["orientation_deg"] < 180
    assert m["defects"] == 0


@pytest.mark.parametrize("t", PER32, ids=lambda t: t.kind)
@pytest.mark.parametrize(("mr", "mc"), [(0, 4), (4, 0), (3, 3), (2, -5), (0, 8), (1, 2)])
@pytest.mark.parametrize("sat", [False, True])
def test_stripes_on_a_periodic_32x32_sheet(t, mr, mc, sat):
    """A pattern the periodic sheet admits, q = 2 pi (mr, mc) / 32 in (row, col) index space: found exactly."""
    rc = np.divmod(np.arange(t.n), t.cols)
    u = 0.6 * np.cos(2 * math.pi * (mr * rc[0] + mc * rc[1]) / 32 + 0.4)
    u = 0.6 * np.tanh(4 * u) if sat else u
    m = measure(t, u)
    q = np.array([mr, mc]) * 2 * math.pi / 32
    kx, ky = p2._cartesian(q[0], q[1], t.kind)
    assert m["pattern_kind"] == "stripes"
    assert m["dominant_wavelength_cells"] == pytest.approx(2 * math.pi / math.hypot(kx, ky), rel=1e-12)
    assert m["orientation_deg"] == pytest.approx(math.degrees(math.atan2(ky, kx)) % 180, abs=1e-9)
    assert m["dominant_wavevector"] == pytest.approx(q if math.atan2(ky, kx) >= 0 else -q, abs=1e-12)
    assert m["defects"] == 0


def test_the_hexagonal_wavevector_is_in_index_space():
    """On a hexagonal sheet [k_row, k_col] is the phase per step down a row and along it: stripes along x (k at 0
    degrees) advance k per column and k/2 per row (rows are sheared by half a cell)."""
    t = Topology((16, 16), "hex")
    m = measure(t, stripes(t, 8, 0))
    k = 2 * math.pi / 8
    assert m["dominant_wavevector"] == pytest.approx([k / 2, k], abs=1e-5)


# ---- spots, labyrinths --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("t", OPEN16 + [Topology((32, 32), "square", True), Topology((32, 32), "hex", True)])
@pytest.mark.parametrize("lam", [4, 8])
@pytest.mark.parametrize("sat", [False, True])
def test_hexagonal_spots(t, lam, sat):
    m = measure(t, hex_spots(t, lam, sat))
    assert m["pattern_kind"] == "spots"
    # an open sheet: three broad peaks pull one another by a few per cent; a periodic one: the nearest admitted q
    assert m["dominant_wavelength_cells"] == pytest.approx(lam, rel=0.07)


@pytest.mark.parametrize("t", [Topology((16, 16), "square"), Topology((32, 32), "square", True)])
@pytest.mark.parametrize("lam", [4, 6, 8])
@pytest.mark.parametrize("sat", [False, True])
def test_square_spots(t, lam, sat):
    m = measure(t, square_spots(t, lam, sat))
    assert m["pattern_kind"] == "spots"
    assert m["dominant_wavelength_cells"] == pytest.approx(lam, rel=0.07 if t.periodic else 0.04)
    assert min(turn(m["orientation_deg"], 0), turn(m["orientation_deg"], 90)) < 3  # along a lattice axis


@pytest.mark.parametrize("t", PER32 + [Topology((32, 32), "square")], ids=lambda t: t.describe())
@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("lam", [6, 8])
def test_labyrinth(t, seed, lam):
    m = measure(t, labyrinth(t, lam, seed))
    assert m["pattern_kind"] == "labyrinth"
    assert m["dominant_wavelength_cells"] == pytest.approx(lam, rel=0.2)  # a ring of width 0.15 |k|


# sheet_8x8's final alpha (lattice, settled from 1.6 s; `run sheet_8x8`, rounded to 1 mrad): one curved + band
# between a - corner and the - far edges, on a sheet smaller than its wavelength (9.75 cells)
SHEET_8X8 = [
    [-0.723, -0.589, -0.006, 0.534, 0.625, 0.337, -0.254, -0.635],
    [-0.589, -0.302, 0.216, 0.607, 0.640, 0.363, -0.228, -0.627],
    [-0.006, 0.216, 0.529, 0.665, 0.655, 0.390, -0.197, -0.615],
    [0.534, 0.607, 0.665, 0.691, 0.657, 0.374, -0.197, -0.605],
    [0.625, 0.640, 0.655, 0.657, 0.598, 0.246, -0.272, -0.607],
    [0.337, 0.363, 0.390, 0.374, 0.246, -0.066, -0.436, -0.623],
    [-0.254, -0.228, -0.197, -0.197, -0.272, -0.436, -0.598, -0.638],
    [-0.635, -0.627, -0.615, -0.605, -0.607, -0.623, -0.638, -0.639],
]


def test_a_band_on_a_sheet_smaller_than_its_wavelength_is_not_spots():
    """Its broad ring gives six-fold order above SPOT_ORDER_MIN but its three sign domains all touch an edge: no
    spot, and the sheet cannot hold one wavelength, so the order is no evidence of spots (it read "spots")."""
    t = Topology((8, 8), "square")
    u = np.asarray(SHEET_8X8).ravel()
    lab, compact = p2.domains(p2.sign_field(u, t), t)
    assert len(compact) == 3 and not compact.any()
    m = measure(t, u)
    assert m["dominant_wavelength_cells"] > 8
    q = m["dominant_wavevector"]
    order = p2.ring_order(u, t, q)
    assert order[2] < p2.STRIPE_ORDER_MIN and order[6] >= p2.SPOT_ORDER_MIN  # the case the rule must not misread
    assert m["pattern_kind"] == "labyrinth"


def test_rest_and_a_uniform_tilt_have_no_pattern():
    t = OPEN16[0]
    noise = 0.01 * np.random.default_rng(1).standard_normal(t.n)
    for u in (noise, noise + 0.4):
        m = measure(t, u)
        assert m == {
            "dominant_wavelength_cells": None,
            "dominant_wavevector": None,
            "orientation_deg": None,
            "pattern_kind": "rest",
            "boundary_length_cells": 0,
            "defects": 0,
        }


@pytest.mark.parametrize("t", [OPEN16[0], PER32[1]], ids=lambda t: t.kind)
def test_an_oscillating_pattern(t):
    """Stripes that swing through zero to the end of the run: an oscillation, measured at the final window's
    largest excursion (the final frame lies near a zero crossing)."""
    tt = np.linspace(0, 2.0, 401)
    u = stripes(t, 8, 30)
    alpha = np.cos(2 * math.pi * tt / 0.2 + 1.5)[:, None] * u[None, :]
    m = p2.measures(tt, alpha, t)
    assert m["pattern_kind"] == "oscillation"
    assert abs(alpha[-1]).max() < 0.1  # the last frame alone would read as rest
    assert m["dominant_wavelength_cells"] == pytest.approx(measure(t, u)["dominant_wavelength_cells"], rel=1e-9)
    # the same stripes, still at the end: not an oscillation
    assert p2.measures(tt, alpha * np.where(tt > 1.0, 0, 1)[:, None] + u * (tt > 1.0)[:, None], t)["pattern_kind"] == (
        "stripes"
    )


# ---- boundary length and defects -----------------------------------------------------------------------------------
def test_boundary_length_counts_the_bonds_a_domain_wall_crosses():
    t = OPEN16[0]
    u = 0.6 * np.cos(2 * math.pi * t.positions()[:, 0] / 8)  # walls between columns 2|3, 6|7, 10|11, 14|15
    assert p2.boundary_length(u, t) == 4 * 16
    tp = Topology((16, 16), "square", True)
    assert p2.boundary_length(u, tp) == 4 * 16  # the wrap bond joins two cells of one sign
    th = Topology((16, 16), "hex")
    assert p2.boundary_length(np.where(th.positions()[:, 1] > 6, 0.5, -0.5), th) == 2 * 16 - 1  # a row's edge


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=2, max_size=24), st.floats(0, 0.3))
def test_on_one_row_the_boundary_length_is_the_chains_domain_walls(profile, threshold):
    u = np.array(profile)
    t = Topology((1, u.size), "square")
    assert p2.boundary_length(u, t, threshold) == domain_walls(u, threshold_rad=threshold)


@pytest.mark.parametrize("t", [Topology((32, 32), "square"), Topology((32, 32), "hex")], ids=lambda t: t.kind)
@pytest.mark.parametrize("sat", [False, True])
def test_dislocations(t, sat):
    cx, cy = t.positions().mean(axis=0)
    one = measure(t, dislocated(t, [(cx + 0.3, cy + 0.4, 1)], sat=sat))
    two = measure(t, dislocated(t, [(cx - 4.3, cy + 0.4, 1), (cx + 4.2, cy - 0.3, -1)], sat=sat))
    assert (one["defects"], two["defects"]) == (1, 2)
    assert one["pattern_kind"] == two["pattern_kind"] == "stripes"


# ---- invariances -------------------------------------------------------------------------------------------------
PATTERNS = {
    "stripes": lambda t, lam, deg: stripes(t, lam, deg),
    "sat_stripes": lambda t, lam, deg: stripes(t, lam, deg, True),
    "hex_spots": lambda t, lam, deg: hex_spots(t, lam),
    "square_spots": lambda t, lam, deg: square_spots(t, lam, True),
}


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from([OPEN16[0], OPEN16[1], PER32[0]]),
    st.sampled_from(sorted(PATTERNS)),
    st.floats(4.0, 10.0),
    st.floats(0.0, 180.0),
    st.integers(0, 2**32 - 1),
)
def test_the_measures_do_not_see_the_sign(t, name, lam, deg, seed):
    u = PATTERNS[name](t, lam, deg) + 0.02 * np.random.default_rng(seed).standard_normal(t.n)
    assert measure(t, -u) == measure(t, u)


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from(PER32),
    st.sampled_from(["stripes", "hex", "square"]),
    st.integers(2, 8),
    st.integers(0, 31),
    st.integers(0, 31),
)
def test_a_translated_periodic_pattern_keeps_its_wavelength_and_kind(t, name, m, dr, dc):
    """Patterns the periodic sheet admits (q = 2 pi m / 32 along a lattice direction), moved by (dr, dc) cells."""
    rc = np.divmod(np.arange(t.n), t.cols)
    q = 2 * math.pi * m / 32
    waves = {"stripes": [(0, 1)], "hex": [(0, 1), (1, 0), (1, -1)], "square": [(0, 1), (1, 0)]}[name]
    if t.kind == "square" and name == "hex":
        waves = [(0, 1), (1, 0)]  # three waves at 60 degrees do not fit a square sheet's admitted q
    u = 0.25 * sum(np.cos(q * (a * rc[0] + b * rc[1])) for a, b in waves)
    moved = np.roll(t.grid(u), (dr, dc), axis=(0, 1)).ravel()
    a, b = measure(t, u), measure(t, moved)
    assert b["pattern_kind"] == a["pattern_kind"] == ("stripes" if name == "stripes" else "spots")
    assert b["dominant_wavelength_cells"] == pytest.approx(a["dominant_wavelength_cells"], rel=1e-12)


# ---- bad input ---------------------------------------------------------------------------------------------------
def test_bad_input_is_refused():
    t = OPEN16[0]
    with pytest.raises(ValueError, match="sheets"):
        p2.measures(*still(np.zeros(16)), Topology.chain(16))
    with pytest.raises(ValueError, match="256 cells"):
        p2.measures(*still(np.zeros(100)), t)
    with pytest.raises(ValueError, match="non-finite"):
        p2.measures(*still(np.full(256, np.nan)), t)


@settings(max_examples=40, deadline=None)
@given(
    st.sampled_from(["square", "hex"]),
    st.booleans(),
    st.integers(1, 12),
    st.integers(1, 12),
    st.integers(2, 12),
    st.sampled_from([0.01, 0.3, 1.0]),
    st.integers(0, 2**32 - 1),
)
def test_any_field_gets_sane_measures(kind, periodic, rows, cols, samples, scale, seed):
    """Whatever the sheet (down to one row) and field: JSON-ready, a known kind, an orientation in [0, 180) and a
    wavelength no shorter than the lattice holds (sqrt(2) square, 1.5 hexagonal)."""
    if periodic:
        rows, cols = rows + 2, cols + 2
    t = Topology((rows, cols), kind, periodic)
    a = scale * np.random.default_rng(seed).standard_normal((samples, t.n))
    m = p2.measures(np.linspace(0, 1, samples), a, t)
    json.dumps(m, allow_nan=False)
    assert m["pattern_kind"] in p2.KINDS
    if m["dominant_wavelength_cells"] is not None:
        assert 0 <= m["orientation_deg"] < 180
        assert m["dominant_wavelength_cells"] >= (1.5 if kind == "hex" else math.sqrt(2)) - 1e-9
    assert m == p2.measures(np.linspace(0, 1, samples), -a, t)


def test_the_kind_table_runs_and_refuses_no_draws(capsys):
    assert main(["--draws", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 7 and out[2].startswith("| stripes | 1/1, 0.0 % |")
    assert main(["--draws", "0"]) == 2
    assert capsys.readouterr().out == ""
