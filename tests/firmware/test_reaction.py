"""Reaction law R_a, R_b and psi' of the cell library against the float reference (docs/physics.md#reaction-torques)."""

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.definition import LIMITS
from tests.firmware.reference import RAD_PER_COUNT, TU_NM, psi_prime_piecewise, reaction, reaction_si

I32 = st.integers(min_value=-(2**31), max_value=2**31 - 1)
NEAR = st.integers(min_value=-3000, max_value=3000)
GAIN = st.integers(min_value=-131071, max_value=131071)
K_MAX = LIMITS["K_MAX_UNM"]  # the firmware's accepted |gain|, uN*m/rad (mc_units.h is generated from it)
K_UNM = st.integers(min_value=-K_MAX, max_value=K_MAX)


def law_dict(r):
    return {k: getattr(r, k) for k in ("g_ab", "g_sigma", "g1", "g2", "astar_q4", "c1")}


def default_law(ffi, lib):
    p = ffi.new("mc_reaction_phys_t*")
    lib.mc_cell_default_params(p)
    r = ffi.new("mc_reaction_t*")
    assert lib.mc_reaction_from_phys(r, p) == lib.MC_OK
    return r


def eval_fixed(ffi, lib, r, a, b):
    ra = ffi.new("int32_t*")
    rb = ffi.new("int32_t*")
    lib.mc_reaction_eval(r, a, b, ra, rb)
    return ra[0], rb[0]


@settings(max_examples=3000, deadline=None)
@given(a=st.one_of(I32, NEAR), b=st.one_of(I32, NEAR))
def test_default_law_within_one_lsb_of_float_reference(fw, a, b):
    ffi, lib = fw
    r = default_law(ffi, lib)
    ra, rb = eval_fixed(ffi, lib, r, a, b)
    ref_a, ref_b = reaction(law_dict(r), a, b)
    assert abs(ra - ref_a) <= 1.0
    assert abs(rb - ref_b) <= 1.0


@settings(max_examples=2000, deadline=None)
@given(
    g_ab=GAIN,
    g_s=GAIN,
    g1=st.integers(1, 131071),
    g2=GAIN,
    astar=st.integers(0, 6400),
    a=st.one_of(I32, NEAR),
    b=st.one_of(I32, NEAR),
)
def test_any_valid_law_within_one_lsb(fw, g_ab, g_s, g1, g2, astar, a, b):
    ffi, lib = fw
    if g2 >= g1:
        g2 = g1 - 1
    r = ffi.new("mc_reaction_t*")
    assert lib.mc_reaction_set_raw(r, g_ab, g_s, g1, g2, astar) == lib.MC_OK
    ra, rb = eval_fixed(ffi, lib, r, a, b)
    ref_a, ref_b = reaction(law_dict(r), a, b)
    assert abs(ra - ref_a) <= 1.0, (ra, ref_a)
    assert abs(rb - ref_b) <= 1.0


@settings(max_examples=2000, deadline=None)
@given(g1=st.integers(1, 131071), g2=GAIN, astar=st.integers(0, 6400), x=st.integers(-2048, 2048))
def test_psi_prime_is_the_piecewise_law_odd_and_continuous(fw, g1, g2, astar, x):
    ffi, lib = fw
    if g2 >= g1:
        g2 = g1 - 1
    r = ffi.new("mc_reaction_t*")
    assert lib.mc_reaction_set_raw(r, 0, 0, g1, g2, astar) == lib.MC_OK
    p = lib.mc_psi_prime(r, x)
    assert abs(p - psi_prime_piecewise(g1, g2, astar / 16.0, x)) <= 1.0
    assert lib.mc_psi_prime(r, -x) == -p  # odd
    # continuous: one count never jumps by more than the steepest slope (+ rounding of c1)
    assert abs(lib.mc_psi_prime(r, min(x + 1, 2048)) - p) <= max(abs(g1), abs(g2)) + 1


def test_default_psi_roots_at_zero_and_alpha_star(fw):
    ffi, lib = fw
    r = default_law(ffi, lib)
    assert r.astar_q4 == 1200  # 3*pi/8 = 75 counts exactly
    assert lib.mc_psi_prime(r, 0) == 0
    assert abs(lib.mc_psi_prime(r, 75)) <= 1 and abs(lib.mc_psi_prime(r, -75)) <= 1
    # breakpoint b = k1 a*/(k1 - k2) = a*/2 for k2 = -k1: psi' peaks there
    assert lib.mc_psi_prime(r, 37) < 0 and lib.mc_psi_prime(r, 38) < 0


@settings(max_examples=1000, deadline=None)
@given(a=st.integers(-600, 600), b=st.integers(-600, 600))
def test_default_law_matches_si_spec_within_quantisation_bound(fw, a, b):
    """Against docs/physics.md#reaction-torques with exact real parameters: the only error is gain quantisation."""
    ffi, lib = fw
    r = default_law(ffi, lib)
    ra, rb = eval_fixed(ffi, lib, r, a, b)
    sa, sb = reaction_si(1 / 50, 9 / 125, 3 / 50, -3 / 50, 3 * math.pi / 8, a * RAD_PER_COUNT, b * RAD_PER_COUNT)
    # each gain is within half a TU/count of exact, c1 within half a TU
    bound = (0.5 * (abs(b - a) + abs(a) + abs(b)) + 0.5 * 75 + 1.5) * TU_NM
    assert abs(ra * TU_NM - sa) <= bound
    assert abs(rb * TU_NM - sb) <= 0.5 * abs(a - b) * TU_NM + TU_NM


@settings(max_examples=500, deadline=None)
@given(k=K_UNM)
def test_gain_conversion_is_within_half_an_lsb(fw, k):
    ffi, lib = fw
    p = ffi.new("mc_reaction_phys_t*")
    lib.mc_cell_default_params(p)
    p.sigma_unm = k
    r = ffi.new("mc_reaction_t*")
    assert lib.mc_reaction_from_phys(r, p) == lib.MC_OK
    exact = k * 1e-6 * RAD_PER_COUNT / TU_NM
    assert abs(r.g_sigma - exact) <= 0.5 + 1e-9


def _tie(k_unm):
    """1 when the exact gain sits within 1e-6 of a rounding tie (either rounding is right), else 0."""
    frac = abs(k_unm * RAD_PER_COUNT * 32.0) % 1.0
    return 1 if abs(frac - 0.5) < 1e-6 else 0


def _gain(k_unm):
    x = k_unm * RAD_PER_COUNT * 32.0
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


@settings(max_examples=500, deadline=None)
@given(
    field=st.sampled_from(["k_ab_unm", "sigma_unm", "k1_unm", "k2_unm", "astar_urad"]),
    value=st.one_of(I32, st.integers(-300000, 300000)),
)
def test_rejected_parameters_leave_running_ones(fw, field, value):
    """A set is accepted exactly when every value is in range and psi' keeps its shape
    (k1 > 0, k1 > k2 in the gains actually held); a rejected set changes nothing."""
    ffi, lib = fw
    c = ffi.new("mc_cell_t*")
    lib.mc_cell_init(c)
    before = law_dict(c.law)
    p = ffi.new("mc_reaction_phys_t*")
    lib.mc_cell_default_params(p)
    setattr(p, field, value)
    lo, hi = (0, LIMITS["ASTAR_MAX_URAD"]) if field == "astar_urad" else (-K_MAX, K_MAX)
    g1, g2 = _gain(p.k1_unm), _gain(p.k2_unm)
    expect_ok = lo <= value <= hi and g1 > 0 and g1 > g2
    rc = lib.mc_cell_set_params(c, p)
    if expect_ok:
        assert rc == lib.MC_OK
        assert abs(c.law.g1 - g1) <= _tie(p.k1_unm) and abs(c.law.g2 - g2) <= _tie(p.k2_unm)
    else:
        assert rc in (lib.MC_ERR_RANGE, lib.MC_ERR_SHAPE)
        assert law_dict(c.law) == before


def test_specific_rejections(fw):
    ffi, lib = fw
    c = ffi.new("mc_cell_t*")
    lib.mc_cell_init(c)
    before = law_dict(c.law)
    p = ffi.new("mc_reaction_phys_t*")
    for field, value, err in [
        ("sigma_unm", 250001, lib.MC_ERR_RANGE),
        ("k1_unm", -60000, lib.MC_ERR_SHAPE),  # k1 <= k2
        ("k1_unm", 0, lib.MC_ERR_SHAPE),
        ("astar_urad", -1, lib.MC_ERR_RANGE),
        ("astar_urad", 7_000_000, lib.MC_ERR_RANGE),
    ]:
        lib.mc_cell_default_params(p)
        setattr(p, field, value)
        assert lib.mc_cell_set_params(c, p) == err, field
        assert law_dict(c.law) == before
    lib.mc_cell_default_params(p)
    p.sigma_unm = 48000  # 6/125
    assert lib.mc_cell_set_params(c, p) == lib.MC_OK
    assert c.law.g_sigma == round(48000e-6 * RAD_PER_COUNT / TU_NM)
    assert lib.mc_cell_set_params(c, ffi.NULL) == lib.MC_ERR_ARG
