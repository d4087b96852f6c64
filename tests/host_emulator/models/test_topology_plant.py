"""The compiled plant on rings and sheets (he_plant_t.bonds): forces against the numpy reference and the weighted
graph Laplacian, Newton's third law over the bonds, no torque from a rigid rotation, the 2-D growth rate of a
Fourier mode against the chain's dispersion relation at the sheet's symbol, and the IMEX sparse solve."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis.stability import growth_rates, reaction_jacobian
from host_emulator.models import ModelOptions, NoiseOptions, Perturbation
from host_emulator.models.hil import HilModel
from host_emulator.models.lattice import LatticeModel
from host_emulator.models.plant import spreads
from host_emulator.models.reference import ReferencePlant
from host_emulator.params import Params

SHEETS = {
    "square 4x4 periodic": dict(shape=(4, 4), lattice="square", boundary="periodic"),
    "square 5x6 periodic": dict(shape=(5, 6), lattice="square", boundary="periodic"),
    "hex 3x4 open": dict(shape=(3, 4), lattice="hex", boundary="open"),
    "hex 4x4 periodic": dict(shape=(4, 4), lattice="hex", boundary="periodic"),
    "ring of 7": dict(cells=7, boundary="periodic"),
}
LAWS = [("cubic", "small"), ("linear", "small"), ("cubic", "geometric")]
SPREAD = NoiseOptions(seed=11, band_spread=0.25, eta_spread=0.1)


def params_of(spec: dict, **kw) -> Params:
    spec = dict(spec)
    if "shape" in spec:
        spec["cells"] = int(np.prod(spec["shape"]))
    return Params(**spec, **kw)


def forces_rel_err(m: LatticeModel, ref: ReferencePlant, x: np.ndarray) -> float:
    F, C = m.forces(0.0, x)
    Fr, Cr = ref.forces(0.0, x)
    assert np.array_equal(C, Cr)
    return float(np.abs(F - Fr).max() / max(np.abs(Fr).max(), 1e-300))


@pytest.mark.parametrize("name", SHEETS)
@pytest.mark.parametrize("bands,geometry", LAWS)
def test_sheet_forces_match_the_reference(name, bands, geometry):
    """Every band law on rings and square and hexagonal sheets, with a band spread (one factor per bond)."""
    p = params_of(SHEETS[name])
    o = ModelOptions(bands=bands, beta_geometry=geometry, noise=SPREAD)
    m, ref = LatticeModel(p, [], o), ReferencePlant(p, o)
    rng = np.random.default_rng(7)
    for scale in (1e-3, 0.1, 0.4):  # 0.4 rad: some bands slack
        assert forces_rel_err(m, ref, scale * rng.standard_normal(2 * p.cells)) < 1e-12


@settings(max_examples=60, deadline=None)
@given(
    x=st.lists(st.floats(-1.0, 1.0, allow_nan=False), min_size=60, max_size=60).map(np.array),
    law=st.sampled_from(LAWS),
    slack_f0=st.booleans(),
)
def test_sheet_forces_match_the_reference_on_random_states(x, law, slack_f0):
    p = params_of(SHEETS["square 5x6 periodic"], slack_f0=slack_f0)
    o = ModelOptions(bands=law[0], beta_geometry=law[1], noise=SPREAD)
    assert forces_rel_err(LatticeModel(p, [], o), ReferencePlant(p, o), x) < 1e-12


@pytest.mark.parametrize("name", SHEETS)
def test_linear_band_torques_are_the_weighted_graph_laplacian(name):
    """Linear bands, no reaction: F = -k L_w x per chain, L_w = Topology.laplacian(band factors) (scipy), an
    assembly independent of both the C plant and the reference."""
    p = params_of(SHEETS[name])
    o = ModelOptions(bands="linear", noise=SPREAD)
    m = LatticeModel(p, [], o)
    m.plant.reaction = m.lib.HE_REACT_NONE
    band, _ = spreads(p, o, p.cells)
    topo = p.topology
    assert band.shape == (2, topo.nbond)
    x = np.random.default_rng(3).standard_normal(2 * p.cells)
    F, _ = m.forces(0.0, x)
    n = p.cells
    for ch, k in enumerate((p.ka_eff, p.kb_eff)):
        want = -k * (topo.laplacian(band[ch]) @ x[ch * n : (ch + 1) * n])
        assert F[ch * n : (ch + 1) * n] == pytest.approx(want, rel=1e-12, abs=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("name", ["ring of 7", "square 5x6 periodic", "hex 4x4 periodic"])
@pytest.mark.parametrize("bands", ["cubic", "linear"])
def test_band_torques_sum_to_zero_over_a_closed_lattice(name, bands):
    """Newton's third law over the bonds: without reaction, motors or pushes the band torques of each chain sum to
    zero (each bond gives -T and +T), whatever the state, slack bands included."""
    p = params_of(SHEETS[name])
    m = LatticeModel(p, [], ModelOptions(bands=bands, noise=SPREAD))
    m.plant.reaction = m.lib.HE_REACT_NONE
    rng = np.random.default_rng(4)
    n = p.cells
    for scale in (1e-2, 0.5):
        F, _ = m.forces(0.0, scale * rng.standard_normal(2 * n))
        for ch in range(2):
            Fc = F[ch * n : (ch + 1) * n]
            assert abs(Fc.sum()) <= 1e-13 * np.abs(Fc).sum()
            assert np.abs(Fc).max() > 0


@pytest.mark.parametrize("name", SHEETS)
@pytest.mark.parametrize("bands,geometry", LAWS)
def test_a_rigid_rotation_gives_no_band_torque(name, bands, geometry):
    """Every cylinder of a chain turned by the same angle (alpha and beta by different ones): every bond's
    stretches are those of rest, so the band torque is zero on every cell, exactly."""
    p = params_of(SHEETS[name])
    m = LatticeModel(p, [], ModelOptions(bands=bands, beta_geometry=geometry, noise=SPREAD))
    m.plant.reaction = m.lib.HE_REACT_NONE
    n = p.cells
    F, _ = m.forces(0.0, np.r_[np.full(n, 0.3), np.full(n, -0.7)])
    assert np.array_equal(F, np.zeros(2 * n))


def mode_state(p: Params, kvec, inertia: bool):
    """The leading eigenvector of mode (k_row, k_col) on the sheet: the 2x2 (4x4 with inertia) linear block of
    docs/physics.md#linear-stability with the chain's q replaced by the sheet's symbol, times cos(k . r)."""
    topo = p.topology
    sym = float(topo.symbol(*kvec))
    a = reaction_jacobian(p) - sym * np.diag([p.ka_eff, p.kb_eff])
    eta = np.array([p.eta_alpha, p.eta_beta])
    if inertia:
        inert = np.array([p.I_a, p.I_b])
        blk = np.block([[np.zeros((2, 2)), np.eye(2)], [a / inert[:, None], -np.diag(eta / inert)]])
    else:
        blk = a / eta[:, None]
    w, v = np.linalg.eig(blk)
    i = int(np.argmax(w.real))
    assert abs(w[i].imag) < 1e-9  # a stationary (Turing) mode
    vec = v[:, i].real / np.abs(v[:, i].real).max()
    rc = np.array([topo.row_col(c) for c in range(1, p.cells + 1)]) - 1
    pattern = np.cos(kvec[0] * rc[:, 0] + kvec[1] * rc[:, 1])
    x0 = np.r_[vec[0] * pattern, vec[1] * pattern]
    v0 = np.r_[vec[2] * pattern, vec[3] * pattern] if inertia else None
    return sym, x0, v0, pattern


@pytest.mark.parametrize("inertia", [False, True])
@pytest.mark.parametrize("mode", [(0, 1), (1, 0), (1, 1)])
def test_sheet_growth_rate_is_the_chain_dispersion_at_the_sheet_symbol(mode, inertia):
    """Periodic 8 x 8 square sheet, linear bands: a single Fourier mode (k_row, k_col) = 2 pi mode / 8 grows (decays) at
    the chain's rate at the wavenumber q with 2 (1 - cos q) = 2 (2 - cos k_row - cos k_col) (the Laplacian enters
    the linear lattice only through its eigenvalue), to 1e-3."""
    p = params_of(dict(shape=(8, 8), lattice="square", boundary="periodic"))
    kvec = (2 * np.pi * mode[0] / 8, 2 * np.pi * mode[1] / 8)
    sym, x0, v0, pattern = mode_state(p, kvec, inertia)
    q = np.arccos(1 - sym / 2)  # the chain's wavenumber with the same symbol (sym <= 4 here)
    theory = growth_rates(p, [q], discrete=True, inertia=inertia)[0, 0]
    assert abs(theory.imag) < 1e-9 and abs(theory.real) > 5  # (0, 1) grows, the shorter modes decay
    m = LatticeModel(p, [], ModelOptions(bands="linear", inertia=inertia, stepper="rk4", dt=2e-5, dt_out=0.01))
    s = m.solver(x0=1e-9 * x0, v0=None if v0 is None else 1e-9 * v0)
    t, a, _ = s.advance_many(15)
    c = a @ pattern / (pattern @ pattern)
    assert np.abs(a).max() < 1e-6  # linear: far below psi's breakpoint
    got = np.polyfit(t, np.log(np.abs(c)), 1)[0]
    assert got == pytest.approx(theory.real, rel=1e-3)
    # the pattern kept its shape: nothing else grew
    assert np.abs(a[-1] / c[-1] - pattern).max() < 1e-6


@pytest.mark.parametrize("name", ["square 4x4 periodic", "hex 3x4 open", "ring of 7"])
def test_imex_sparse_solve_is_backward_euler_of_the_linear_lattice(name):
    """Linear bands, no reaction, inertia: one IMEX step solves (I + h C + h^2 K) v1 = I v0 + h F(x0) exactly; the
    conjugate-gradient solve on the bonds against a dense solve of the same matrix (Topology.laplacian)."""
    p = params_of(SHEETS[name])
    o = ModelOptions(bands="linear", stepper="imex_euler", noise=SPREAD)
    m = LatticeModel(p, [], o)
    m.plant.reaction = m.lib.HE_REACT_NONE
    n, h = p.cells, 2e-3
    rng = np.random.default_rng(9)
    x0, v0 = 0.1 * rng.standard_normal(2 * n), rng.standard_normal(2 * n)
    F, C = m.forces(0.0, x0)
    band, _ = spreads(p, o, n)
    want = []
    for ch, (k, inert) in enumerate(((p.ka_eff, p.I_a), (p.kb_eff, p.I_b))):
        sl = slice(ch * n, (ch + 1) * n)
        W = np.diag(inert + h * C[sl]) + h * h * k * p.topology.laplacian(band[ch]).toarray()
        want.append(np.linalg.solve(W, inert * v0[sl] + h * F[sl]))
    x, v = x0.copy(), v0.copy()
    ffi, lib = m.ffi, m.lib
    t = ffi.new("double *", 0.0)
    rc = lib.he_advance(
        m.plant, lib.HE_STEP_IMEX, h, 1, t, ffi.from_buffer("double[]", x), ffi.from_buffer("double[]", v)
    )
    assert rc == lib.HE_OK
    assert v == pytest.approx(np.concatenate(want), rel=1e-11, abs=1e-11)
    assert x == pytest.approx(x0 + h * v, rel=1e-15, abs=1e-300)


@pytest.mark.parametrize("model", [LatticeModel, HilModel])
def test_a_push_spreads_over_the_sheet_not_along_the_cell_numbers(model):
    """A 5 x 5 open sheet pushed at its centre (cell 13): its four neighbours (cells 8, 12, 14, 18; 8 and 18 are
    five cell numbers away) move alike, and more than cell 11 (two numbers away, two bonds on the sheet) and the
    corners. Both models, end to end through their solvers."""
    p = Params(cells=25, shape=(5, 5), lattice="square", boundary="open", bemf_comp=False)
    push = [Perturbation(cell=13, chain="alpha", torque_Nm=0.03, start_s=0.0, duration_s=0.03)]
    s = model(p, push, ModelOptions(dt_out=0.01)).solver()
    _, a, _ = s.advance_many(4)
    alpha = a[-1]
    nb = alpha[[7, 11, 13, 17]]
    assert np.isfinite(a).all() and abs(alpha[12]) > 0.05
    assert np.abs(nb - nb.mean()).max() < 0.05 * abs(nb.mean()) + 0.02  # hil: encoder counts of 2 pi / 400
    assert abs(nb.mean()) > 1.5 * max(abs(alpha[10]), abs(alpha[0]), abs(alpha[24]))


def _always_on_zero_push(m) -> None:
    """A perturbation of 0 N*m that is always on: every hil plant step then goes through he_advance."""
    k = m.plant.npert
    m.plant.npert = k + 1
    m.plant.pert[k].cell, m.plant.pert[k].chain, m.plant.pert[k].torque = 0, 0, 0.0
    m.plant.pert[k].t0, m.plant.pert[k].t1 = -1.0, 1e9


@pytest.mark.parametrize("name", ["square 5x6 periodic", "hex 3x4 open", "ring of 7"])
def test_fast_hil_edge_step_is_bit_identical_to_the_generic_step(name):
    """The hil loop's fast plant step on an edge list (plant_step_edges) against he_advance, over pushes that
    drive the cells' reaction through the firmware, with band and viscosity spreads."""
    p = params_of(SHEETS[name], bemf_comp=False)
    push = [Perturbation(cell=2, chain="alpha", torque_Nm=0.03, start_s=0.0, duration_s=0.03)]
    o = ModelOptions(dt_out=0.01, noise=NoiseOptions(seed=2, band_spread=0.05, eta_spread=0.05))
    out = []
    for generic in (False, True):
        m = HilModel(p, push, o)
        if generic:
            _always_on_zero_push(m)
        _, a, b = m.solver().advance_many(20)
        out.append((a, b))
    assert np.abs(out[0][0]).max() > 1e-2
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])


@pytest.mark.parametrize("where", [0, 13, 30 + 7, 59])
def test_fast_hil_edge_step_reports_what_the_generic_step_reports(where):
    """Diverged, non-finite and over-stretched states: the same code and time from the fast edge step as from
    he_advance, wherever the bad entry sits on a 5 x 6 periodic sheet."""
    p = params_of(SHEETS["square 5x6 periodic"], bemf_comp=False)
    cases = {"DIVERGED": (2000.0, None), "NONFINITE": (float("nan"), None), "BAND": (3.0, -3.0)}
    for code, (val, nb) in cases.items():
        got = []
        for generic in (False, True):
            m = HilModel(p, [], ModelOptions())
            if generic:
                _always_on_zero_push(m)
            s = m.solver()
            lib = m.lib
            s.x[where] = val
            if nb is not None:  # the cell to the right on the sheet (a bond of the edge list)
                ch, j = divmod(where, 30)
                r, c = divmod(j, 6)
                s.x[ch * 30 + r * 6 + (c + 1) % 6] = nb
            s._pt[0] = 0.0
            rc = lib.he_hil_run(s.h, 3, s._pt, s._px, s._pv)
            got.append((rc, s._pt[0]))
        assert got[0] == got[1], code
        assert got[0][0] == getattr(lib, f"HE_ERR_{code}")
