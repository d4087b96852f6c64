"""The plant's force kernels: the unrolled (SSE2) bond and reaction loops give the bits of the plain he_band_torque /
he_reaction loop, and the switch list covers every kink of the force law (F is smooth wherever no side changes)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.models import ModelOptions
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params

N = 7  # odd: the two-lane loops and their scalar tails both run


def model(bands="cubic", geometry="small", slack_f0=True, limit=True, spread=True):
    from host_emulator.models import NoiseOptions

    noise = NoiseOptions(seed=5, band_spread=0.2) if spread else NoiseOptions()
    opts = ModelOptions(bands=bands, beta_geometry=geometry, noise=noise)
    return LatticeModel(Params(cells=N, slack_f0=slack_f0, actuator_limit=limit), [], opts)


def plain_forces(m: LatticeModel, x: np.ndarray) -> np.ndarray:
    """he_plant_torques as the general loop writes it, in Python floats (IEEE double, no contraction): the same
    operations in the same order, through the one-bond and one-cell C functions."""
    lib, p, n = m.lib, m.plant, m.n
    F = [0.0] * (2 * n)
    for ch in range(2):
        for j in range(n):
            F[ch * n + j] = p.mgain[ch][j] * p.volt[ch][j]
        for j in range(n - 1):
            T = lib.he_band_torque(p, ch, j, x[ch * n + j], x[ch * n + j + 1])
            F[ch * n + j] -= T
            F[ch * n + j + 1] += T
    ra, rb = m.ffi.new("double *"), m.ffi.new("double *")
    lim = p.react_limit
    for j in range(n):
        lib.he_reaction(p, x[j], x[n + j], ra, rb)
        a = lim if ra[0] > lim else (-lim if ra[0] < -lim else ra[0])
        b = lim if rb[0] > lim else (-lim if rb[0] < -lim else rb[0])
        F[j] += a
        F[n + j] += b
    return np.array(F)


states = st.lists(st.floats(-2.5, 2.5, allow_nan=False), min_size=2 * N, max_size=2 * N).map(np.array)


@settings(max_examples=150, deadline=None)
@given(x=states, slack_f0=st.booleans(), limit=st.booleans(), scale=st.sampled_from([1e-3, 0.1, 1.0]))
def test_unrolled_bond_and_reaction_loops_keep_every_bit(x, slack_f0, limit, scale):
    """Slack bands (|dx| > ~0.5 rad), both pieces of psi', the clip and -0.0 all occur over these states."""
    m = model(slack_f0=slack_f0, limit=limit)
    x = x * scale
    F, _ = m.forces(0.0, x)
    assert np.array_equal(F.view(np.uint64), plain_forces(m, x).view(np.uint64))


def sides(m: LatticeModel, x: np.ndarray) -> bytes:
    buf = m.ffi.new("unsigned char[]", max(1, m.lib.he_plant_nswitch(m.plant)))
    k = m.lib.he_plant_switches(m.plant, m.ffi.from_buffer("double[]", np.ascontiguousarray(x)), buf)
    assert k == m.lib.he_plant_nswitch(m.plant) <= 9 * m.n
    return bytes(m.ffi.buffer(buf, k))


@settings(max_examples=60, deadline=None)
@given(
    x=states,
    d=st.lists(st.floats(-3, 3, allow_nan=False), min_size=2 * N, max_size=2 * N).map(np.array),
    geometry=st.sampled_from(["small", "geometric"]),
    bands=st.sampled_from(["cubic", "linear"]),
    limit=st.booleans(),
)
def test_force_is_smooth_wherever_no_switch_changes_side(x, d, geometry, bands, limit):
    """Along a line x + s d, s = 0 .. 1 in 400 steps (it crosses slack bands, psi's kink and the clip many times),
    the fourth difference of F over any 5 consecutive points vanishes (to rounding; to h^4 times the fourth
    derivative for the geometric beta bands) wherever every switch keeps its side over them: every kink of the
    law is in the switch list."""
    m = model(bands=bands, geometry=geometry, limit=limit)
    pts = [x + s * d for s in np.linspace(0.0, 1.0, 401)]
    F = np.array([m.forces(0.0, q)[0] for q in pts])
    sd = [sides(m, q) for q in pts]
    d4 = F[4:] - 4 * F[3:-1] + 6 * F[2:-2] - 4 * F[1:-3] + F[:-4]
    tol = (1e-6 if geometry == "geometric" and bands == "cubic" else 1e-10) * (np.abs(F).max() + 1e-6)
    for i in range(len(d4)):
        if len(set(sd[i : i + 5])) == 1:
            assert np.abs(d4[i]).max() <= tol, (i, np.abs(d4[i]).max(), tol)


def test_a_kink_inside_the_segment_shows_in_the_fourth_difference_and_in_the_sides():
    """The converse on one known kink, psi' at alpha = b*: the fourth difference is large across it, and exactly
    one switch changes side. (So the smoothness test above can fail.)"""
    m = model(spread=False)
    p = m.params
    bstar = p.k1 * p.alpha_star / (p.k1 - p.k2)
    h = 1e-3
    x = np.zeros(2 * N)
    d = np.zeros(2 * N)
    d[3] = 1.0
    pts = [x + (bstar - 2.5 * h + k * h) * d for k in range(5)]
    F = np.array([m.forces(0.0, q)[0] for q in pts])
    d4 = F[4] - 4 * F[3] + 6 * F[2] - 4 * F[1] + F[0]
    assert np.abs(d4).max() > 1e-6
    s0, s4 = sides(m, pts[0]), sides(m, pts[4])
    assert sum(a != b for a, b in zip(s0, s4)) == 1
