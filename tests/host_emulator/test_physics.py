"""Every copy of the reaction law, its Gershgorin bound and the cubic band slope against one float reference.

Copies: firmware fixed point (mc_reaction.h, via cffi), C float plant (he_plant.c), Python (physics.py) and the
py-pde expressions built from it. Reference: tests/firmware/reference.py (reaction_si), finite differences and
numpy's eigenvalue/row-sum arithmetic, none of which shares code with the copies.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator import physics
from host_emulator.models.options import ModelOptions
from host_emulator.models.plant import build_plant
from host_emulator.params import BAND_A_COEF, BAND_B_COEF, Params
from tests.firmware.reference import RAD_PER_COUNT, TU_NM, reaction_si

ANGLE = st.floats(min_value=-4.0, max_value=4.0, allow_nan=False)
GAIN = st.floats(min_value=-0.2, max_value=0.2, allow_nan=False)


def _laws():
    """Parameter sets: the experiment's three sigmas and a few other valid shapes (k1 > max(k2, 0))."""
    out = [Params(sigma=s) for s in (6 / 125, 9 / 125, 14 / 125)]
    out += [Params(k_ab=0.05, k1=0.1, k2=0.02, alpha_star=0.5, sigma=-0.03), Params(k_ab=-0.01, k1=0.02, k2=-0.2)]
    return out


LAWS = _laws()


@pytest.fixture(scope="module")
def plants(fw):
    ffi, lib = fw
    return [build_plant(ffi, lib, p, ModelOptions(), 2, [], ideal_reaction=True) for p in LAWS]


def _ref(p, a, b):
    return reaction_si(p.k_ab, p.sigma, p.k1, p.k2, p.alpha_star, a, b)


@settings(max_examples=300, deadline=None)
@given(i=st.integers(0, len(LAWS) - 1), a=ANGLE, b=ANGLE)
def test_c_float_and_python_reaction_match_the_reference(fw, plants, i, a, b):
    ffi, lib = fw
    p = LAWS[i]
    ra_ref, rb_ref = _ref(p, a, b)
    ra, rb = ffi.new("double *"), ffi.new("double *")
    lib.he_reaction(plants[i], a, b, ra, rb)
    assert ra[0] == pytest.approx(ra_ref, rel=1e-12, abs=1e-15)
    assert rb[0] == pytest.approx(rb_ref, rel=1e-12, abs=1e-15)
    pa, pb = physics.reaction(p, a, b)
    assert pa == pytest.approx(ra_ref, rel=1e-12, abs=1e-15)
    assert pb == pytest.approx(rb_ref, rel=1e-12, abs=1e-15)
    assert p.psi_prime(a) == pytest.approx(p.k_ab * (b - a) - p.sigma * b - ra_ref, rel=1e-9, abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(a=st.integers(-2048, 2048), b=st.integers(-2048, 2048), i=st.integers(0, 2))
def test_firmware_fixed_point_reaction_matches_the_reference(fw, a, b, i):
    """The cells' law (gains rounded to the firmware's units) within its quantisation of the SI reference."""
    ffi, lib = fw
    p = LAWS[i]
    phys = ffi.new("mc_reaction_phys_t *")
    phys.k_ab_unm, phys.sigma_unm = round(p.k_ab * 1e6), round(p.sigma * 1e6)
    phys.k1_unm, phys.k2_unm, phys.astar_urad = round(p.k1 * 1e6), round(p.k2 * 1e6), round(p.alpha_star * 1e6)
    r = ffi.new("mc_reaction_t *")
    assert lib.mc_reaction_from_phys(r, phys) == lib.MC_OK
    ra, rb = ffi.new("int32_t *"), ffi.new("int32_t *")
    lib.mc_reaction_eval(r, a, b, ra, rb)
    ra_ref, rb_ref = _ref(p, a * RAD_PER_COUNT, b * RAD_PER_COUNT)
    # gain rounding (1 uN*m/rad and 1/32 of a count for a*) times |angle| <= 2048 counts, plus 1 TU per term
    tol = 3 * 2048 * RAD_PER_COUNT * 1e-6 + 0.1 * p.k1 * RAD_PER_COUNT + 8 * TU_NM
    assert abs(ra[0] * TU_NM - ra_ref) <= tol
    assert abs(rb[0] * TU_NM - rb_ref) <= tol


def test_pypde_expressions_are_the_same_law():
    """The py-pde strings (sympy syntax) evaluated with numpy against the reference, on and off the branches."""
    a = np.linspace(-4, 4, 2001)
    b = np.linspace(3, -3, 2001)
    for p in LAWS:
        ea, eb = physics.pypde_reaction(p)
        env = {"Abs": np.abs, "a": a, "b": b}
        ra, rb = eval(ea, env), eval(eb, env)  # noqa: S307 - our own generated expression
        ref = np.array([_ref(p, x, y) for x, y in zip(a, b)])
        assert np.allclose(ra, ref[:, 0], rtol=1e-9, atol=1e-12)
        assert np.allclose(rb, ref[:, 1], rtol=1e-9, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(i=st.integers(0, len(LAWS) - 1), a=ANGLE, b=ANGLE)
def test_reaction_jacobian_is_the_derivative_of_the_reference(i, a, b):
    p = LAWS[i]
    kink = p.k1 * p.alpha_star / (p.k1 - p.k2)
    h = 1e-6
    if abs(abs(a) - kink) < 2 * h:
        return  # psi' has a kink there
    jac = physics.reaction_jacobian(p, a)
    for col, (da, db) in enumerate(((h, 0.0), (0.0, h))):
        hi, lo = _ref(p, a + da, b + db), _ref(p, a - da, b - db)
        for row in range(2):
            assert jac[row, col] == pytest.approx((hi[row] - lo[row]) / (2 * h), rel=1e-6, abs=1e-9)
    assert np.array_equal(physics.reaction_jacobian(p, np.array([a, a]))[..., 1], jac)  # vectorised form


def test_gershgorin_bound_c_python_and_numeric(fw, plants):
    """C (he_react_stiffness) == Python (reaction_gershgorin) == max over alpha of the Jacobian's absolute row sums."""
    _, lib = fw
    for p, plant in zip(LAWS, plants):
        alphas = np.linspace(-4, 4, 4001)
        jac = physics.reaction_jacobian(p, alphas)  # (2, 2, N)
        rows = np.abs(jac).sum(axis=1).max(axis=1)
        py = physics.reaction_gershgorin(p)
        assert py == pytest.approx(tuple(rows), rel=1e-12)
        assert (lib.he_react_stiffness(plant, 0), lib.he_react_stiffness(plant, 1)) == pytest.approx(py, rel=1e-15)
        # and it bounds every eigenvalue of the reaction Jacobian (what the step limits rely on)
        eig = np.abs(np.linalg.eigvals(np.moveaxis(jac, -1, 0))).max()
        assert eig <= max(py) * (1 + 1e-12)


@settings(max_examples=200, deadline=None)
@given(d=st.floats(min_value=-0.02, max_value=0.03, allow_nan=False), ch=st.integers(0, 1))
def test_cubic_slope_c_python_and_finite_difference(fw, d, ch):
    ffi, lib = fw
    coef = (BAND_A_COEF, BAND_B_COEF)[ch]
    c = ffi.new("double[4]", list(coef))
    h = 1e-7
    ref = (np.polyval(coef[::-1], d + h) - np.polyval(coef[::-1], d - h)) / (2 * h)  # numpy's own polynomial
    assert physics.band_slope(coef, d) == pytest.approx(ref, rel=1e-6, abs=1e-6)
    assert lib.he_cubic_slope(c, d) == pytest.approx(physics.band_slope(coef, d), rel=1e-15, abs=1e-12)
    assert lib.he_cubic(c, d) == pytest.approx(np.polyval(coef[::-1], d), rel=1e-12, abs=1e-15)
    assert physics.band_force(coef, d) == pytest.approx(np.polyval(coef[::-1], d), rel=1e-12, abs=1e-15)


def test_bond_slope_is_the_derivative_of_the_band_torque(fw):
    """he_bond_slope (the IMEX stepper's stiffness, moved into he_plant.c) against finite differences of the torque."""
    ffi, lib = fw
    plant = build_plant(ffi, lib, Params(), ModelOptions(bands="cubic"), 3, [], ideal_reaction=True)
    h = 1e-7
    for ch in (0, 1):
        for dx in (-0.2, -0.05, 0.0, 0.03, 0.3):
            if ch == 1 and abs(abs(dx) * 0.02 - 0.005) < 1e-6:
                continue
            tau = lib.he_band_torque
            fd = (tau(plant, ch, 0, dx + h, 0.0) - tau(plant, ch, 0, dx - h, 0.0)) / (2 * h)
            assert lib.he_bond_slope(plant, ch, 0, dx) == pytest.approx(fd, rel=1e-5, abs=1e-9)
    assert math.isfinite(lib.he_damping(plant, 0, 0))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-5, 5), min_size=1, max_size=20))
def test_psi_prime_and_slope_match_the_reference(values):
    """physics.psi_prime_and_slope (the continuum's rhs and Jacobian, Params.psi_prime) against the reference's
    psi' (read off reaction_si at beta = 0) and its finite differences (moved from the continuum model's tests)."""
    p = Params()
    a = np.array(values)
    pp, slope = physics.psi_prime_and_slope(p, a)

    def ref_psi(x):
        return np.array([-_ref(p, v, 0.0)[0] - p.k_ab * v for v in x])  # R_a(x, 0) = -k_ab x - psi'(x)

    assert np.allclose(pp, ref_psi(a), atol=1e-15)
    assert np.array_equal(np.asarray(p.psi_prime(a)), pp)
    h = 1e-6
    fd = (ref_psi(a + h) - ref_psi(a - h)) / (2 * h)
    b = p.k1 * p.alpha_star / (p.k1 - p.k2)
    away = np.abs(np.abs(a) - b) > 2 * h  # the kinks have no derivative
    assert np.allclose(slope[away], fd[away], atol=1e-6)
