"""dop853 (Dormand-Prince 8(5,3)): the adaptive lattice runs against independent references (scipy's DOP853 at rtol
1e-12, the exact linear solution), its order with fixed steps, the step-rejection, switch-landing and failure paths,
its stable limit, and sampled runs bit-identical to per-sample ones."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

from host_emulator.benchmarks import workprecision as wp
from host_emulator.models import ConfigError, ModelOptions, NumericalInstability
from host_emulator.models.lattice import LatticeModel
from host_emulator.models.options import parse_options
from host_emulator.params import Params
from tests.host_emulator.linear_lattice import linear_system


@pytest.fixture(scope="module")
def exp3():
    """Experiment 3 over 1 s (the push, pattern growth, 4 crossings of psi's kink) and scipy's DOP853 on the same
    compiled right-hand side at rtol 1e-12: a reference that shares only the physics with the C stepper."""
    scene = wp.lattice_scene(1.0)
    n2 = 2 * scene.cells
    t_eval = wp.output_times(1.0, scene.options.dt_out)
    ref, _ = wp.solve_segments(wp.compiled_rhs(scene), np.zeros(2 * n2), scene, t_eval, "DOP853", 1e-12, 1e-14)
    return scene, ref[:, :n2]


def adaptive_run(scene, tol, land=True, h0=None, x0=None):
    """States (T, 2n) at the output times and the solver's info, through the public solver."""
    m = LatticeModel(scene.params, scene.perturbations, replace(scene.options, stepper="dop853", tol=tol, dt=None))
    s = m.solver(x0=x0)
    s._ad.land = int(land)
    if h0 is not None:
        s._ad.h = h0
    x = wp._sampled_states(s, scene.t_end_s, m.n)
    return x, s.info()


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8])
def test_error_against_scipy_reference_is_below_tolerance(exp3, tol):
    scene, ref = exp3
    x, info = adaptive_run(scene, tol)
    err = np.abs(x - ref).max()
    assert err < tol, (tol, err, info)
    assert info["switch_landings"] >= 4  # psi's kink is crossed (cells 7-9 swing past b* during the push)


def test_error_falls_with_the_tolerance(exp3):
    scene, ref = exp3
    errs = [np.abs(adaptive_run(scene, tol)[0] - ref).max() for tol in (1e-3, 1e-5, 1e-7, 1e-9)]
    assert all(a > 3 * b for a, b in zip(errs, errs[1:])), errs


def test_landing_on_the_kinks_is_what_makes_tight_tolerances_pay(exp3):
    """Without landing on the force law's switches the error at tol 1e-9 is set by the steps across psi's
    kink (their error estimate is wrong there); with it the error is 10x or more smaller."""
    scene, ref = exp3
    with_land = np.abs(adaptive_run(scene, 1e-9)[0] - ref).max()
    without = np.abs(adaptive_run(scene, 1e-9, land=False)[0] - ref).max()
    assert without > 10 * with_land, (without, with_land)


def test_rejected_steps_recover_from_a_far_too_large_first_step(exp3):
    """A first step of 0.5 s (130x the stable limit) is rejected until the controller is back in range; the run
    is as accurate as one that starts from the driver's own initial step."""
    scene, ref = exp3
    x, info = adaptive_run(scene, 1e-7, h0=0.5)
    assert info["rejected_steps"] >= 3
    assert np.abs(x - ref).max() < 1e-7


def test_matches_the_exact_linear_solution():
    """Linear bands (the reaction's kink never reached at 1e-3 rad): error against expm of the linear system."""
    p = Params(cells=5, sigma=14 / 125, eta_scale=10)
    x0 = 1e-3 * np.sin(np.arange(10) + 0.5)
    for tol in (1e-5, 1e-9):
        m = LatticeModel(p, [], ModelOptions(bands="linear", stepper="dop853", tol=tol, dt_out=0.05))
        s = m.solver(x0=x0)
        for _ in range(4):
            s.advance()
        exact = scipy.linalg.expm(linear_system(p) * 0.2) @ np.r_[x0, np.zeros(10)]
        assert np.abs(s.x - exact[:10]).max() < tol * 1e-3, tol  # angles of 1e-3 rad: tol is relative


def test_fixed_steps_are_eighth_order():
    """he_advance with HE_STEP_DOP853 (the hil's use): halving the step divides the error by ~2^8 (steps of 0.9
    and 0.45 x the stable limit; 2.4e-4 and 1e-6 relative error)."""
    p = Params(cells=5, sigma=14 / 125, eta_scale=1)
    x0 = 1e-3 * np.sin(np.arange(10) + 0.5)
    exact = scipy.linalg.expm(linear_system(p) * 0.2) @ np.r_[x0, np.zeros(10)]
    errs = []
    for dt in (0.004, 0.002):
        m = LatticeModel(p, [], ModelOptions(bands="linear", stepper="dop853", dt_out=0.2))
        s = m.solver(x0=x0)
        rc = m.lib.he_advance(m.plant, s.sid, dt, round(0.2 / dt), s._pt, s._px, s._pv)
        assert rc == m.lib.HE_OK
        errs.append(np.abs(s.x - exact[:10]).max() / 1e-3)
    order = math.log2(errs[0] / errs[1])
    assert 7.0 < order < 9.5, (errs, order)


@pytest.mark.parametrize("inertia", [True, False])
def test_fixed_step_limit_is_stable_and_beyond_blows_up(inertia):
    p = Params(cells=16, sigma=14 / 125, eta_scale=10)
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper="dop853", inertia=inertia))
    h, _ = m.step_limit()
    x0 = 1e-3 * np.cos(np.pi * np.arange(32))  # zig-zag: the stiffest modes
    s = m.solver(x0=x0)
    assert m.lib.he_advance(m.plant, s.sid, 0.9 * h, int(2.0 / h), s._pt, s._px, s._pv) == m.lib.HE_OK
    assert np.abs(s.x).max() < 1e-2
    s2 = m.solver(x0=x0)
    rc = m.lib.he_advance(m.plant, s2.sid, 2.0 * h, 20000, s2._pt, s2._px, s2._pv)
    assert rc in (m.lib.HE_ERR_NONFINITE, m.lib.HE_ERR_DIVERGED)


def test_adaptive_run_stays_stable_at_a_loose_tolerance():
    """tol 1e-2 on the stiffest lattice: the step control holds the step inside the stability region by itself
    (the error estimate sees the growth), so a decaying zig-zag decays."""
    p = Params(cells=16, sigma=14 / 125, eta_scale=10)
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper="dop853", tol=1e-2, dt_out=0.1))
    s = m.solver(x0=1e-3 * np.cos(np.pi * np.arange(32)))
    for _ in range(20):
        s.advance()
    assert np.abs(s.x).max() < 1e-3


def test_sampled_run_is_bit_identical_to_per_sample_calls(exp3):
    scene, _ = exp3
    opts = replace(scene.options, stepper="dop853", tol=1e-6)
    a = LatticeModel(scene.params, scene.perturbations, opts).solver()
    b = LatticeModel(scene.params, scene.perturbations, opts).solver()
    _, al, be = a.advance_many(100)
    for k in range(100):
        b.advance()
        assert np.array_equal(b.x[:16], al[k]) and np.array_equal(b.x[16:], be[k])
    assert a.info()["force_evaluations"] == b.info()["force_evaluations"]  # the stored derivative reused


def test_tolerance_below_the_smallest_step_fails_with_its_own_error(exp3):
    """A smallest step the controller must undercut gives HE_ERR_TOL, reported naming the tolerance."""
    scene, _ = exp3
    m = LatticeModel(scene.params, scene.perturbations, replace(scene.options, stepper="dop853", tol=1e-10))
    s = m.solver()
    s._ad.h_min = 1e-3  # the push needs steps of ~1e-4 s at this tolerance
    with pytest.raises(NumericalInstability, match=r"smallest step .* tolerance cannot be met.*tol 1e-10"):
        s.advance_many(30)


def test_unstable_lattice_stops_with_a_clear_error():
    """sigma 14/125 without the actuator limit grows until a band leaves the fit's range: an error naming the
    cause, not a silent NaN or a step size shrinking forever."""
    m = LatticeModel(Params(cells=16, sigma=14 / 125, actuator_limit=False), [], ModelOptions(stepper="dop853"))
    s = m.solver(x0=np.full(32, 1e-3))
    with pytest.raises(NumericalInstability, match="band stretched beyond|diverged"):
        s.advance_many(1000)
    assert s.t < 10


def test_tol_option_is_validated():
    assert parse_options({"tol": 1e-7}).tol == 1e-7
    for bad in (0, -1e-6, 1.0, 1e-20, "1e-6", math.nan):
        with pytest.raises(ConfigError, match="model_options.tol"):
            parse_options({"tol": bad})


def test_hil_loop_runs_dop853_fixed_steps():
    from host_emulator.controller import build_solver, run_solver
    from host_emulator.scene import load_scene

    sc = load_scene("default", ["t_end_s=0.3", 'model_options.stepper="dop853"', "model_options.substeps=1"])
    rk = load_scene("default", ["t_end_s=0.3", 'model_options.stepper="rk4"', "model_options.substeps=8"])
    a = run_solver(build_solver(sc), 0.3)
    b = run_solver(build_solver(rk), 0.3)
    assert a.info["stepper"] == "dop853"
    assert np.abs(a.alpha - b.alpha).max() < 0.02  # at most a count's flip of the quantised loop (15.7 mrad)
