"""The 2-D linear theory (analysis.sheet, analysis.sheet_modes) against independent references: the full linearised
sheet assembled here by neighbour arithmetic, root-finding on the scalar relation, scipy's dense eig."""

import math

import numpy as np
import pytest
import scipy.linalg
from scipy.optimize import brentq, minimize_scalar

from host_emulator.analysis import chain, sheet, sheet_modes
from host_emulator.analysis.stability import Theory, dispersion, growth_rates_at_q
from host_emulator.params import Params
from host_emulator.topology import Topology

LAT = Theory("lattice", True, True, 0.0)
OVERDAMPED = Theory("lattice", False, True, 0.0)
SQ3 = math.sqrt(3.0)


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between two multisets of complex numbers, paired by optimal assignment."""
    from scipy.optimize import linear_sum_assignment

    d = np.abs(a[:, None] - b[None, :])
    r, c = linear_sum_assignment(d)
    return float(d[r, c].max())


def _neighbours(rows, cols, kind, periodic):
    """Each cell's neighbour pairs with their bond (r, c, r2, c2), written from the lattice's geometry (the
    square's four, the hexagon's six: +-col, +-row, and (+1 row, -1 col), (-1 row, +1 col)), not from Topology."""
    steps = [(0, 1), (1, 0)] + ([(1, -1)] if kind == "hex" else [])
    out = []
    for r in range(rows):
        for c in range(cols):
            for dr, dc in steps:
                r2, c2 = r + dr, c + dc
                if periodic:
                    r2, c2 = r2 % rows, c2 % cols
                elif not (0 <= r2 < rows and 0 <= c2 < cols):
                    continue
                out.append((r, c, r2, c2))
    return out


def _full_system(p: Params, rows, cols, kind, periodic, inertia, factor=lambda i, j: 1.0, eta_f=None):
    """The linearised sheet's system matrix (E^-1 A, or the companion with inertia) assembled cell by cell."""
    n = rows * cols
    kab, sig, k2 = (np.broadcast_to(np.asarray(getattr(p, k), float), (n,)) for k in ("k_ab", "sigma", "k2"))
    a = np.zeros((2 * n, 2 * n))
    for j in range(n):
        a[j, j] = -kab[j] - k2[j]
        a[j, n + j] = kab[j] - sig[j]
        a[n + j, j] = kab[j]
        a[n + j, n + j] = -kab[j]
    for r, c, r2, c2 in _neighbours(rows, cols, kind, periodic):
        i, j = r * cols + c, r2 * cols + c2
        for off, k in ((0, p.ka_eff), (n, p.kb_eff)):
            w = k * factor(i + off, j + off)
            a[off + i, off + i] -= w
            a[off + j, off + j] -= w
            a[off + i, off + j] += w
            a[off + j, off + i] += w
    eta = np.concatenate([np.full(n, p.eta_alpha), np.full(n, p.eta_beta)])
    if eta_f is not None:
        eta = eta * eta_f.ravel()
    if not inertia:
        return a / eta[:, None]
    inert = np.concatenate([np.full(n, p.I_a), np.full(n, p.I_b)])
    m = np.zeros((4 * n, 4 * n))
    m[: 2 * n, 2 * n :] = np.eye(2 * n)
    m[2 * n :, : 2 * n] = a / inert[:, None]
    m[2 * n :, 2 * n :] = -np.diag(eta / inert)
    return m


@pytest.mark.parametrize(
    "rows,cols,kind,periodic",
    [(4, 5, "square", True), (5, 3, "hex", True), (4, 5, "square", False), (3, 4, "hex", False)],
)
@pytest.mark.parametrize("inertia", [False, True])
def test_finite_sheet_eigenvalues_are_the_dispersion_at_its_allowed_wavevectors(rows, cols, kind, periodic, inertia):
    p = Params(
        sigma=9 / 125, cells=rows * cols, shape=(rows, cols), lattice=kind, boundary=["open", "periodic"][periodic]
    )
    want = np.linalg.eigvals(_full_system(p, rows, cols, kind, periodic, inertia))
    modes = sheet.allowed_wavevectors(p.topology)
    assert len(modes) == rows * cols
    got = growth_rates_at_q(p, [m["q"] for m in modes], inertia=inertia).ravel()
    assert _match(got, want) <= 1e-9 * float(np.abs(want).max())


def test_hexagonal_plane_waves_in_the_positions_metric():
    """exp(i k . x) over Topology.positions() of a periodic hexagonal sheet is an eigenvector of its Laplacian with
    eigenvalue symbol(k): the Cartesian convention (k_row, k_col) is the positions' own."""
    t = Topology((6, 8), "hex", True)
    lap = t.laplacian().toarray()
    xy = t.positions()  # (x along a row, y down the rows)
    allowed = sheet.allowed_wavevectors(t)
    for m in allowed:
        kr, kc = m["k"]
        u = np.exp(1j * (kc * xy[:, 0] + kr * xy[:, 1]))
        assert np.allclose(lap @ u, m["q"] * u, atol=1e-10)
    assert len(allowed) == 48


@pytest.mark.parametrize("deg", [0.0, 17.0, 30.0, 45.0, 90.0, 123.0])
def test_symbols_at_small_k(deg):
    """Square: |k|^2; hexagonal (unit bond length): 3/2 |k|^2, isotropic, both to O(|k|^4)."""
    k = 1e-3
    kr, kc = k * math.sin(math.radians(deg)), k * math.cos(math.radians(deg))
    assert float(sheet.symbol("square", kr, kc)) == pytest.approx(k * k, rel=1e-6)
    assert float(sheet.symbol("hex", kr, kc)) == pytest.approx(1.5 * k * k, rel=1e-6)
    assert float(sheet.symbol("hex", kr, kc, discrete=False)) == pytest.approx(1.5 * k * k, rel=1e-12)


def _lead_continuum(p: Params, inertia: bool, q: float) -> float:
    """Largest Re s of det(I s^2 + E s - Jr + q K) = 0, written out here (2x2 reaction Jacobian at rest)."""
    jr = np.array([[-p.k_ab - p.k2, p.k_ab - p.sigma], [p.k_ab, -p.k_ab]])
    a = jr - q * np.diag([p.ka_eff, p.kb_eff])
    eta = np.array([p.eta_alpha, p.eta_beta])
    if not inertia:
        return float(np.linalg.eigvals(a / eta[:, None]).real.max())
    inert = np.array([p.I_a, p.I_b])
    m = np.block([[np.zeros((2, 2)), np.eye(2)], [a / inert[:, None], -np.diag(eta / inert)]])
    return float(np.linalg.eigvals(m).real.max())


@pytest.mark.parametrize("inertia", [False, True])
@pytest.mark.parametrize("band_scale", [1.0, 0.5])
def test_continuum_annulus_radii_are_the_roots_of_the_scalar_relation(inertia, band_scale):
    p = Params(sigma=9 / 125, band_scale=band_scale, cells=256, shape=(16, 16), lattice="square")
    th = Theory("lattice", inertia, False, 0.0)
    an = sheet.annulus(p, th)
    assert an["regime"] == "stationary_pattern" and len(an["intervals"]) == 1

    def g(k):
        return _lead_continuum(p, inertia, k * k)

    best = minimize_scalar(lambda k: -g(k), bounds=(0.05, 3.0), method="bounded", options={"xatol": 1e-12})
    k_in, k_out = brentq(g, 1e-6, best.x, xtol=1e-14), brentq(g, best.x, 10.0, xtol=1e-14)
    got = an["intervals"][0]["continuum"]["k"]
    assert got == pytest.approx([k_in, k_out], rel=1e-8)
    assert an["k"] == got  # the continuum theory reads its own radii
    assert sheet.fastest(p, th)["continuum"]["k"] == pytest.approx(best.x, rel=1e-5)
    hexa = sheet.annulus(p.with_overrides(lattice="hex"), th)["intervals"][0]["continuum"]["k"]
    assert hexa == pytest.approx([k_in / math.sqrt(1.5), k_out / math.sqrt(1.5)], rel=1e-8)


@pytest.mark.parametrize("kind", ["square", "hex"])
def test_lattice_annulus_edges_are_neutral_and_the_fastest_contour_is_the_chains_fastest(kind):
    p = Params(sigma=9 / 125, cells=64, shape=(8, 8), lattice=kind)
    an, fa = sheet.annulus(p, LAT), sheet.fastest(p, LAT)
    for name, deg in sheet.DIRECTIONS[kind].items():
        u = np.array([math.sin(math.radians(deg)), math.cos(math.radians(deg))])
        for k in an["intervals"][0]["discrete"][name]["k"]:
            s = sheet.growth_rates_2d(p, k * u[0], k * u[1], theory=LAT)[0]
            assert abs(s.real) < 1e-6 * fa["growth_per_s"]
        kf = fa["discrete"][name]["k"]
        assert float(sheet.symbol(kind, kf * u[0], kf * u[1])) == pytest.approx(fa["q"], rel=1e-10)
    if kind == "square":  # along an axis the square lattice is the chain
        d = dispersion(Params(sigma=9 / 125), theory=LAT)
        assert fa["lambda_cells"] == pytest.approx(d["fastest_lambda_cells"], rel=1e-7)
        assert an["lambda_cells"] == pytest.approx(d["unstable_set_cells"][0], rel=1e-7)


def test_other_regimes():
    """6/125: the longest waves grow (a disc, inner radius 0); 14/125 with inertia: only the uniform oscillation;
    14/125 without inertia: nothing grows."""
    sq = {"cells": 256, "shape": (16, 16), "lattice": "square"}
    broad = sheet.annulus(Params(sigma=6 / 125, **sq), OVERDAMPED)
    assert broad["regime"] == "broadband_pattern" and broad["intervals"][0]["continuum"]["k"][0] == 0.0
    assert broad["intervals"][0]["discrete"]["axis"]["lambda_cells"][1] is None
    osc = sheet.annulus(Params(sigma=14 / 125, **sq), LAT)
    assert osc["regime"] == "uniform_oscillation" and osc["intervals"][0]["kind"] == "oscillatory"
    assert sheet.fastest(Params(sigma=14 / 125, **sq), LAT)["lambda_cells"] is None
    rest = sheet.annulus(Params(sigma=14 / 125, **sq), OVERDAMPED)
    assert rest["regime"] == "rest" and rest["intervals"] == [] and rest["lambda_cells"] is None


@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_acceptance_a_16x16_sheet_grows_within_25_percent_of_the_fastest_wavelength(boundary):
    p = Params(sigma=9 / 125, cells=256, shape=(16, 16), lattice="square", boundary=boundary)
    fs = sheet.finite_sheet(p, LAT)
    lo, hi = sheet.annulus(p, LAT)["intervals"][0]["discrete"]["axis"]["lambda_cells"]
    top = fs["fastest_mode"]
    assert fs["in_annulus"] and top["growth_per_s"] > 0
    assert lo * 0.97 < top["lambda_cells"] < hi  # the diagonal's band is a little narrower than the axis'
    assert abs(fs["relative_to_fastest"]) <= 0.25
    assert fs["unstable"] == sum(m["growth_per_s"] > 0 for m in fs["modes"]) > 0


def test_heterogeneous_sheet_leading_eigenvalue_against_scipy():
    rng = np.random.default_rng(7)
    rows = cols = 6
    n = rows * cols
    p = Params(
        cells=n,
        shape=(rows, cols),
        lattice="square",
        sigma=tuple(rng.uniform(0.05, 0.1, n)),
        k_ab=tuple(rng.uniform(0.015, 0.03, n)),
        k2=tuple(rng.uniform(-0.08, -0.04, n)),
    )

    def factor(i, j):  # a stiffness factor per bond, a function of its two ends
        return 0.85 + 0.3 * ((7 * min(i, j) + 3 * max(i, j)) % 11) / 10

    t = p.topology
    band = np.array([[factor(i + off, j + off) for i, j in t.bonds] for off in (0, n)])
    eta = rng.uniform(0.7, 1.3, (2, n))
    for inertia in (False, True):
        th = Theory("lattice", inertia, True, 0.0)
        want = scipy.linalg.eigvals(_full_system(p, rows, cols, "square", False, inertia, factor, eta))
        lead = want[np.argmax(want.real)]
        res = sheet_modes.sheet_modes(p, th, band_factors=band, eta_factors=eta, method="dense")
        assert abs(res["modes"][0]["growth_per_s"] - lead.real) <= 1e-9 * abs(lead)
        assert _match(res["growth_per_s"], want) <= 1e-8 * float(np.abs(want).max())
        assert res["modes"][0]["alpha_grid"].shape == (rows, cols)
        sparse = sheet_modes.sheet_modes(p, th, band_factors=band, eta_factors=eta, method="sparse", count=4)
        got = [m["growth_per_s"] for m in sparse["modes"]]
        assert got == pytest.approx([m["growth_per_s"] for m in res["modes"][:4]], rel=1e-9)


def test_uniform_sheet_mode_shape_reads_the_allowed_wavevector():
    p = Params(sigma=9 / 125, cells=144, shape=(12, 12), lattice="square", boundary="periodic")
    res = sheet_modes.sheet_modes(p, OVERDAMPED, count=1)  # sparse: more than DENSE_MAX_CELLS cells
    fs = sheet.finite_sheet(p, OVERDAMPED)
    assert res["method"] == "sparse"
    assert res["modes"][0]["growth_per_s"] == pytest.approx(fs["fastest_mode"]["growth_per_s"], rel=1e-10)
    assert res["modes"][0]["lambda_cells"] == pytest.approx(fs["fastest_mode"]["lambda_cells"], rel=1e-12)


@pytest.mark.parametrize("inertia", [False, True])
def test_a_chain_through_the_general_code_is_analysis_chain(inertia):
    rng = np.random.default_rng(3)
    n = 9
    p = Params(cells=n, sigma=tuple(rng.uniform(0.0, 0.15, n)), k2=tuple(rng.uniform(-0.1, -0.01, n)))
    band, eta = rng.uniform(0.85, 1.15, (2, n)), rng.uniform(0.7, 1.3, (2, n))
    th = Theory("hil", inertia, True, 1e-4)
    want = chain.chain_modes(p, th, band_factors=band, eta_factors=eta)
    got = sheet_modes.sheet_modes(p, th, band_factors=band[:, : n - 1], eta_factors=eta, count=4 * n)
    assert np.abs(got["growth_per_s"] - want["growth_per_s"]).max() <= 1e-10 * np.abs(want["growth_per_s"]).max()
    for a, b in zip(got["modes"], want["modes"]):
        assert np.allclose(a["alpha"], b["alpha"], atol=1e-10)


def test_bad_input_is_refused():
    p = Params(sigma=9 / 125, cells=16, shape=(4, 4), lattice="square")
    with pytest.raises(ValueError, match="band_factors"):
        sheet_modes.sheet_matrices(p, band_factors=np.ones((2, 3)))
    with pytest.raises(ValueError, match="method"):
        sheet_modes.sheet_modes(p, method="fast")
    with pytest.raises(ValueError, match="chain"):
        sheet.annulus(Params(sigma=9 / 125))


@pytest.mark.parametrize("bands", ["cubic", "linear"])
@pytest.mark.parametrize("geometry", ["small", "geometric"])
def test_the_lattice_forces_are_odd(bands, geometry):
    """docs/sheets.md#stripes-or-spots: F(-x) = -F(x) exactly (psi' odd, the band pairs and the actuator clip
    symmetric), even with per-cell laws and k1 != k2: no quadratic term, whatever the parameters."""
    from host_emulator.models import ModelOptions, make_model

    rng = np.random.default_rng(11)
    n = 6
    p = Params(cells=n, sigma=tuple(rng.uniform(0.04, 0.12, n)), k1=0.11, alpha_star=tuple(rng.uniform(0.5, 1.5, n)))
    m = make_model("lattice", p, [], ModelOptions(bands=bands, beta_geometry=geometry))
    for _ in range(20):
        x = rng.normal(0.0, 1.2, 2 * n)
        fp, _ = m.forces(0.0, x)
        fm, _ = m.forces(0.0, -x)
        assert np.array_equal(fm, -fp)


def test_brillouin_zone_edges_and_their_symbols():
    """The zone's edge along the reported directions: square X (pi, symbol 4) and M (pi sqrt 2, 8); hexagonal K
    along a bond (4 pi / 3, symbol 9, its largest) and M between two (2 pi / sqrt 3, 8)."""
    for kind, deg, edge, q in (
        ("square", 0.0, math.pi, 4.0),
        ("square", 45.0, math.pi * math.sqrt(2), 8.0),
        ("hex", 0.0, 4 * math.pi / 3, 9.0),
        ("hex", 30.0, 2 * math.pi / SQ3, 8.0),
    ):
        assert sheet.zone_edge(kind, deg) == pytest.approx(edge, rel=1e-12)
        u = (math.sin(math.radians(deg)), math.cos(math.radians(deg)))
        assert float(sheet.symbol(kind, edge * u[0], edge * u[1])) == pytest.approx(q, rel=1e-12)


def test_theory_of_sheet_is_the_annulus_and_the_fastest_modes():
    """The keys a sheet's summary may carry (analysis.summary), JSON-ready and equal to what annulus, fastest and
    finite_sheet say."""
    import json

    p = Params(sigma=9 / 125, cells=256, shape=(16, 16), lattice="hex", boundary="periodic")
    d = sheet.theory_of_sheet(p, LAT)
    json.dumps(d, allow_nan=False)
    assert d["regime"] == "stationary_pattern"
    assert d["unstable_lambda_cells"] == sheet.annulus(p, LAT)["lambda_cells"]
    assert d["fastest_lambda_cells"] == sheet.fastest(p, LAT)["lambda_cells"]
    top = sheet.finite_sheet(p, LAT)["fastest_mode"]
    assert d["sheet_fastest_lambda_cells"] == top["lambda_cells"] and d["sheet_unstable_modes"] == 12
