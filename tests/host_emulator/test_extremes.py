"""Stability at the extremes of the physics: every case ends with a sound result, checked against linear
theory where there is one, or with a clear error naming the limit; never a silent NaN or blow-up."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from host_emulator.models import ModelOptions, NumericalInstability, Perturbation
from host_emulator.models.hil import HilModel
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params

COUNT = 2 * math.pi / 400
PUSH = [Perturbation(8, "alpha", 0.02, 0.1, 0.1)]


def lattice_matrix(p, inertia=True):
    """Linearised free-end lattice (linear bands, inner psi' branch) from docs/physics.md#equations-of-motion, state (x,
    v) or x."""
    n = p.cells
    lap = np.zeros((n, n))
    for j in range(n - 1):
        lap[j, j] += 1
        lap[j + 1, j + 1] += 1
        lap[j, j + 1] -= 1
        lap[j + 1, j] -= 1
    K = np.block([[p.ka_eff * lap, np.zeros((n, n))], [np.zeros((n, n)), p.kb_eff * lap]])
    J = np.block(
        [[(-p.k_ab - p.k2) * np.eye(n), (p.k_ab - p.sigma) * np.eye(n)], [p.k_ab * np.eye(n), -p.k_ab * np.eye(n)]]
    )
    eta = np.r_[np.full(n, p.eta_alpha), np.full(n, p.eta_beta)]
    if not inertia:
        return (J - K) / eta[:, None]
    moi = np.r_[np.full(n, p.I_a), np.full(n, p.I_b)]
    return np.block([[np.zeros((2 * n, 2 * n)), np.eye(2 * n)], [(J - K) / moi[:, None], -np.diag(eta / moi)]])


def max_growth(p, inertia=True):
    return float(np.linalg.eigvals(lattice_matrix(p, inertia)).real.max())


def leading_mode(p, inertia=True):
    """(rate, x0, v0) of the eigenvalue with the largest real part; a real start vector in its (2-D) eigenspace."""
    w, V = np.linalg.eig(lattice_matrix(p, inertia))
    k = int(np.argmax(w.real))
    y = np.real(V[:, k]) + np.imag(V[:, k])
    n2 = 2 * p.cells
    y = y / np.abs(y[:n2]).max()
    return float(w[k].real), y[:n2], (y[n2:] if inertia else None)


def measured_growth(p, inertia, stepper="rk4", t_fit=(0.1, 0.5), dt=None):
    """Growth rate of the leading linear mode (linear bands) started at 1e-9 rad along its eigenvector: slope of
    log max|x| over t_fit (stopped early once 1e-4 rad: still linear, far below the psi' breakpoint)."""
    _, x0, v0 = leading_mode(p, inertia)
    s = LatticeModel(p, [], ModelOptions(bands="linear", inertia=inertia, stepper=stepper, dt=dt, dt_out=0.005)).solver(
        x0=1e-9 * x0, v0=None if v0 is None else 1e-9 * v0
    )
    t, y = [], []
    while s.t < t_fit[1] - 1e-9 and np.abs(s.x).max() < 1e-4:
        s.advance()
        t.append(s.t)
        y.append(np.log(np.abs(s.x).max()))
    t, y = np.array(t), np.array(y)
    sel = t >= min(t_fit[0], t[len(t) // 2])
    return np.polyfit(t[sel], y[sel], 1)[0]


# ---------------------------------------------------------------- inertia -> 0 (overdamped limit)
@pytest.mark.parametrize("scale", [1e-3, 1e-6])
def test_inertia_to_zero_limit_and_imex_match_overdamped(scale):
    """I -> 0: the explicit steppers' computed limit shrinks with I (it is refused, naming it, above that);
    the IMEX stepper runs at a step set by the reaction only and converges to the overdamped model."""
    p = Params(cells=16).with_overrides(I_a=6.39e-7 * scale, I_b=3.13e-7 * scale)
    lim_rk4, chain = LatticeModel(p, PUSH, ModelOptions(stepper="rk4")).step_limit()
    lim_1, _ = LatticeModel(Params(cells=16), PUSH, ModelOptions(stepper="rk4")).step_limit()
    assert lim_rk4 < lim_1 * 10 * math.sqrt(scale)  # ~ I/eta: the stiff damping mode
    with pytest.raises(ValueError, match=rf"exceeds the stable step limit {lim_rk4:.4g} s of stepper 'rk4'"):
        LatticeModel(p, PUSH, ModelOptions(stepper="rk4", dt=1e-3)).solver()
    imex = LatticeModel(p, PUSH, ModelOptions(stepper="imex_euler", dt=2e-4)).solver()
    over = LatticeModel(Params(cells=16), PUSH, ModelOptions(stepper="imex_euler", dt=2e-4, inertia=False)).solver()
    for _ in range(60):
        imex.advance()
        over.advance()
    assert np.abs(over.x).max() > 0.3
    # the difference vanishes linearly with I (measured ~4 rad x scale): the overdamped limit
    assert np.abs(imex.x - over.x).max() < 10 * scale


def test_overdamped_growth_matches_theory_with_imex_at_large_step():
    """Overdamped model, IMEX at 10x the explicit RK4 limit: growth of the fastest mode as linear theory."""
    p = Params(cells=16, sigma=6 / 125)
    lim_rk4, _ = LatticeModel(p, [], ModelOptions(stepper="rk4", inertia=False, bands="linear")).step_limit()
    lim_imex, _ = LatticeModel(p, [], ModelOptions(stepper="imex_euler", inertia=False, bands="linear")).step_limit()
    dt = 0.8 * lim_imex
    assert dt > 3 * lim_rk4
    got = measured_growth(p, False, "imex_euler", t_fit=(0.1, 0.5), dt=dt)
    theory = max_growth(p, inertia=False)
    assert theory > 5
    assert got == pytest.approx(theory, rel=0.05)  # first order: ~ dt * rate^2 / 2 bias


# ---------------------------------------------------------------- eta_beta below 0.1 eta_a
@pytest.mark.parametrize("gamma", [0.03, 0.01, 0.001])
def test_eta_beta_below_source_choice(gamma):
    """Below gamma = 0.1 the beta chain is under-damped; the step limit is set by stiffness, not damping, so the
    run stays numerically sound; what changes is the physics: the growth rate of the linear lattice (with
    inertia) is what the eigen-analysis says (growing or decaying)."""
    p = Params(cells=16, sigma=9 / 125, gamma=gamma)
    theory = max_growth(p)
    got = measured_growth(p, True, "rk4")
    assert got == pytest.approx(theory, rel=0.05, abs=0.5)
    from host_emulator.analysis.stability import dispersion

    d = dispersion(p, inertia=True, n_cells=16)
    assert d["lattice_fastest_mode"]["growth_per_s"] == pytest.approx(theory, rel=0.02, abs=0.2)


def test_eta_beta_tiny_pushed_lattice_ends_sound():
    """gamma = 0.001 with the exp. 3 push and the non-linear plant: either a finite state or a stop that names
    the cause; never NaN."""
    p = Params(cells=16, gamma=0.001)
    s = LatticeModel(p, PUSH, ModelOptions()).solver()
    try:
        for _ in range(300):
            s.advance()
        assert np.all(np.isfinite(s.x)) and np.abs(s.x).max() < 100
    except NumericalInstability as e:
        assert "band stretched" in str(e) or "diverged" in str(e)


# ---------------------------------------------------------------- eta ten-fold
def test_eta_tenfold_rest_and_decay():
    """eta x10 at sigma 14/125: a small state decays at the linear rate; rest stays exactly rest."""
    p = Params(cells=16, sigma=14 / 125, eta_scale=10)
    theory = max_growth(p)
    assert theory < 0
    got = measured_growth(p, True, "rk4", t_fit=(0.2, 1.0))
    assert got == pytest.approx(theory, rel=0.05)
    s = LatticeModel(p, [], ModelOptions()).solver()
    for _ in range(100):
        s.advance()
    assert not s.x.any() and not s.v.any()


@pytest.mark.parametrize("stepper", ["euler", "symplectic_euler", "rk4", "noh_bathe", "imex_euler"])
def test_eta_tenfold_every_stepper_runs_pushed_scene(stepper):
    """exp. 4 (eta x10, sigma 14/125): every stepper at its default step (a quarter of its computed limit,
    which the ten-fold damping shrinks for the explicit ones) follows rk4 at a tiny step and decays."""
    p = Params(cells=16, sigma=14 / 125, eta_scale=10)
    push = [Perturbation(8, "alpha", 0.04, 0.1, 0.1)]
    s = LatticeModel(p, push, ModelOptions(stepper=stepper)).solver()
    ref = LatticeModel(p, push, ModelOptions(stepper="rk4", dt=2e-5)).solver()
    peak = 0.0
    for k in range(300):
        s.advance()
        ref.advance()
        peak = max(peak, np.abs(s.x).max())
        if k == 149:
            mid = np.abs(s.x).max()
    assert peak > 0.1 and np.abs(s.x).max() < 0.5 * mid
    assert np.abs(s.x - ref.x).max() < (2e-2 if stepper in ("euler", "symplectic_euler", "imex_euler") else 1e-4)


# ---------------------------------------------------------------- stiff bands
def test_stiff_bands_limit_named_and_imex_agrees():
    """Bands x100 (eta x10, so no inertial oscillation blurs the comparison): the explicit limit drops ~10x and a
    larger dt is refused naming it; IMEX runs at 5x the explicit limit and agrees with rk4 at its own step."""
    p1 = Params(cells=16, eta_scale=10)
    p = p1.with_overrides(band_scale=p1.band_scale * 100)
    lim1, _ = LatticeModel(p1, PUSH, ModelOptions(stepper="symplectic_euler")).step_limit()
    lim, chain = LatticeModel(p, PUSH, ModelOptions(stepper="symplectic_euler")).step_limit()
    assert lim < lim1 / 7
    with pytest.raises(ValueError, match=rf"{lim:.4g} s of stepper 'symplectic_euler' \(stiffest mode on the {chain}"):
        LatticeModel(p, PUSH, ModelOptions(stepper="symplectic_euler", dt=2 * lim)).solver()
    rk = LatticeModel(p, PUSH, ModelOptions(stepper="rk4")).solver()
    im = LatticeModel(p, PUSH, ModelOptions(stepper="imex_euler", dt=5 * lim)).solver()
    for _ in range(50):
        rk.advance()
        im.advance()
    assert np.abs(rk.x).max() > 5e-3
    assert np.abs(im.x - rk.x).max() < 0.01 * np.abs(rk.x).max()


# ---------------------------------------------------------------- sigma at the regime boundaries
def _boundaries(inertia, eta_scale=1.0):
    f = lambda s: max_growth(Params(cells=16, sigma=s, eta_scale=eta_scale), inertia)  # noqa: E731
    grid = np.linspace(0.02, 0.3, 141)
    vals = [f(s) for s in grid]
    return [brentq(f, grid[i], grid[i + 1], xtol=1e-10) for i in range(len(grid) - 1) if vals[i] * vals[i + 1] < 0]


@pytest.mark.parametrize("inertia,eta_scale", [(False, 1.0), (True, 10.0)])
def test_sigma_at_regime_boundaries(inertia, eta_scale):
    """At sigma 3 % either side of each boundary where the fastest growth changes sign, the measured growth has
    the sign and size the eigen-analysis gives; the overdamped boundaries bracket analysis.stability's regimes."""
    b = _boundaries(inertia, eta_scale)
    assert b, "no regime boundary found"
    for sb in b:
        for s in (sb * 0.97, sb * 1.03):
            p = Params(cells=16, sigma=s, eta_scale=eta_scale)
            theory = max_growth(p, inertia)
            got = measured_growth(p, inertia, "rk4", t_fit=(0.5, 2.0))
            assert np.sign(got) == np.sign(theory) and got == pytest.approx(theory, rel=0.1, abs=0.05)
    if not inertia:
        from host_emulator.analysis.stability import dispersion

        regimes = [
            dispersion(Params(cells=16, sigma=s), inertia=False, n_cells=16)["regime"]
            for s in (b[0] * 0.97, b[-1] * 1.03)
        ]
        assert regimes[0] != regimes[1]


def test_inertia_at_eta_x1_has_no_stable_sigma():
    """A finding, kept as a check: with inertia at eta x1 the ideal lattice is unstable for every sigma in
    0.02..0.3 (least unstable near sigma 0.09, still growing at ~20/s): the long-wave inertial oscillation. The
    rig is rescued by the motors' back-EMF damping (docs/emulator.md); eta x10 restores a stable regime."""
    assert _boundaries(True, 1.0) == []
    g = [max_growth(Params(cells=16, sigma=s), True) for s in np.linspace(0.02, 0.3, 29)]
    assert min(g) > 10
    assert _boundaries(True, 10.0)


# ---------------------------------------------------------------- one simulated hour
def test_one_simulated_hour_lattice_pattern_stays():
    """3600 s of the pushed 16-cell lattice (accuracy fast: rk4 at 0.8 x its computed limit): the pattern it
    reaches by 60 s is still there, unchanged, after an hour; no drift, no NaN."""
    p = Params(cells=16)
    lim, _ = LatticeModel(p, PUSH, ModelOptions(stepper="rk4")).step_limit()
    s = LatticeModel(p, PUSH, ModelOptions(stepper="rk4", dt=0.8 * lim, dt_out=1.0)).solver()
    for _ in range(60):
        s.advance()
    x10 = s.x.copy()
    for _ in range(3540):
        s.advance()
    assert s.t == pytest.approx(3600.0)
    assert np.abs(x10).max() > 0.5
    assert np.abs(s.x - x10).max() < 1e-9 and np.abs(s.v).max() < 1e-9


def test_one_simulated_hour_hil_at_rest():
    """An hour of the rig at 100 Hz control (the slowest rate the firmware accepts; 5 plant steps per tick from
    the stable limit): rest stays exactly rest; no faults."""
    p = Params(cells=16, control_rate_hz=100.0, bemf_comp=False)
    s = HilModel(p, [], ModelOptions(dt_out=10.0)).solver()
    assert s.substeps >= 2  # tick 10 ms > the plant's stable step: sub-stepped, not refused
    for _ in range(360):
        s.advance()
    assert s.t == pytest.approx(3600.0)
    assert not s.x.any() and s.info()["faults"] == 0 and s.encoder_errors() == 0


# ---------------------------------------------------------------- lattice size 1 .. 4096
def test_single_cell_matches_reaction_theory():
    """One cell (no bands): a small tilt evolves as the 2x2 (4x4 with inertia) reaction system."""
    import scipy.linalg

    p = Params(cells=1, sigma=14 / 125, eta_scale=10)
    A = lattice_matrix(p)
    x0 = np.array([1e-3, -5e-4])
    s = LatticeModel(p, [], ModelOptions(bands="linear", stepper="rk4", dt=1e-5, dt_out=0.05)).solver(x0=x0)
    s.advance()
    exact = scipy.linalg.expm(A * 0.05) @ np.r_[x0, 0, 0]
    assert np.abs(s.x - exact[:2]).max() < 1e-9


@pytest.mark.parametrize("model", ["lattice", "hil"])
def test_4096_cells_runs_and_does_not_depend_on_size(model):
    """4096 cells: runs finite; 0.3 s after a push on cell 8 the first 64 cells are exactly those of a 256-cell
    lattice (the signal has not reached either far end: nothing depends on the array size). The compiled plant
    refuses more than HE_MAX_CELLS = 65536 (a 256 x 256 sheet)."""

    def run(n):
        cls = LatticeModel if model == "lattice" else HilModel
        s = cls(Params(cells=n, bemf_comp=False), PUSH, ModelOptions()).solver()
        for _ in range(30):
            s.advance()
        return s.x

    small, big = run(256), run(4096)
    assert np.all(np.isfinite(big)) and np.abs(big[:16]).max() > 0.2
    assert np.abs(big[:64] - small[:64]).max() < 1e-12
    assert np.abs(big[4096 : 4096 + 64] - small[256 : 256 + 64]).max() < 1e-12
    with pytest.raises(ValueError, match="65536"):
        LatticeModel(Params(cells=65537), [], ModelOptions())


def test_scene_accepts_4096_cells_and_refuses_more():
    from host_emulator.models.options import ConfigError
    from host_emulator.scene import load_scene

    assert load_scene("exp5_rest", ["cells=4096"]).cells == 4096
    with pytest.raises(ConfigError, match="1..4096"):
        load_scene("exp5_rest", ["cells=4097"])


# ---------------------------------------------------------------- control rates 100 Hz .. 50 kHz
@pytest.mark.parametrize("rate", [100, 1000, 10000, 50000])
def test_control_rates_pushed_rig_is_sound(rate):
    """At every control rate the firmware accepts, the pushed rig stays finite, the push deflects cell 8, and
    the plant is sub-stepped below its stable limit (never refused)."""
    p = Params(cells=16, control_rate_hz=float(rate), bemf_comp=False)
    s = HilModel(p, PUSH, ModelOptions()).solver()
    assert 1.0 / rate / s.substeps <= s.limit
    peak = 0.0
    for _ in range(50):
        s.advance()
        peak = max(peak, abs(s.x[7]))
    assert np.all(np.isfinite(s.x)) and peak > 0.3


@pytest.mark.parametrize("rate", [99, 50001])
def test_control_rate_outside_firmware_range_is_refused(rate):
    with pytest.raises(ValueError, match="control_rate_hz 100..50000"):
        HilModel(Params(cells=4, control_rate_hz=float(rate)), [], ModelOptions())


@pytest.mark.parametrize("inertia,eta_scale", [(False, 1.0), (True, 10.0)])
def test_sigma_at_unconditional_boundary_uniform_mode(inertia, eta_scale):
    """sigma = -k2 (= 0.06) separates the unconditionally unstable regime (the uniform mode grows) from the
    conditional one: 3 % either side, a uniform tilt grows or decays at the rate of the kappa = 0 block."""
    from host_emulator.analysis.stability import dispersion

    for s, sign in ((0.06 * 0.97, 1), (0.06 * 1.03, -1)):
        p = Params(cells=8, sigma=s, eta_scale=eta_scale)
        A2 = np.array([[-p.k_ab - p.k2, p.k_ab - p.sigma], [p.k_ab, -p.k_ab]])
        eta, moi = np.array([p.eta_alpha, p.eta_beta]), np.array([p.I_a, p.I_b])
        B = (
            A2 / eta[:, None]
            if not inertia
            else np.block([[np.zeros((2, 2)), np.eye(2)], [A2 / moi[:, None], -np.diag(eta / moi)]])
        )
        w, V = np.linalg.eig(B)
        k = int(np.argmax(w.real))
        y = np.real(V[:, k]) / np.abs(np.real(V[:2, k])).max()
        x0 = 1e-6 * np.repeat(y[:2], p.cells)
        v0 = 1e-6 * np.repeat(y[2:], p.cells) if inertia else None
        sol = LatticeModel(p, [], ModelOptions(bands="linear", inertia=inertia, stepper="rk4", dt_out=0.05)).solver(
            x0=x0, v0=v0
        )
        t, yy = [], []
        for _ in range(20):
            sol.advance()
            t.append(sol.t)
            yy.append(np.log(np.abs(sol.x).max()))
        got = np.polyfit(t, yy, 1)[0]
        assert np.sign(got) == sign and got == pytest.approx(w[k].real, rel=0.05)
        d = dispersion(p, inertia=inertia, n_cells=8)
        assert np.sign(d["uniform_mode_growth_per_s"]) == sign
