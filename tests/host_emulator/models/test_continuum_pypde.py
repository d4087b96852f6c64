"""The sheet continuum against py-pde on the same PDE: same grid (py-pde's CartesianGrid and its own Laplacian), same
initial state, a short run into psi's outer branches; the final fields agree within both solvers' tolerances."""

import numpy as np
import pytest

from host_emulator.models.continuum import simulate_continuum
from host_emulator.params import Params
from host_emulator.physics import reaction

pde = pytest.importorskip("pde", reason="py-pde is not installed (the `bench` extra: pip install -e '.[bench]')")

N = 8  # 8 x 8 cells, one volume per cell: a second of py-pde's numpy stepping
T_END = 0.04
PYPDE_TOL = 1e-9  # py-pde's adaptive Runge-Kutta-Fehlberg: max-norm absolute error per step
OURS_RTOL = 1e-8


class SheetPDE(pde.PDEBase):
    """eta_a a_t = ka_eff lap a + R_a, eta_b b_t = kb_eff lap b + R_b; the Laplacian is py-pde's (scipy backend,
    no numba), the law physics.reaction."""

    def __init__(self, params, grid, bc):
        super().__init__()
        self.p = params
        self.lap = grid.make_operator("laplace", bc=bc, backend="scipy")

    def evolution_rate(self, state, t=0):
        p = self.p
        a, b = state.data
        ra, rb = reaction(p, a, b)
        out = state.copy()
        out.data[0] = (p.ka_eff * self.lap(a) + ra) / p.eta_alpha
        out.data[1] = (p.kb_eff * self.lap(b) + rb) / p.eta_beta
        return out


def initial(x, y):
    """A bump of 1.1 rad (beyond psi's breakpoint 0.59 rad) off the sheet's centre, on a seeded ripple."""
    rng = np.random.default_rng(7)
    return 1.1 * np.exp(-((x - 3.2) ** 2 + (y - 4.6) ** 2) / 3.0) + 0.05 * rng.uniform(-1, 1, x.shape), 0.0 * x


@pytest.mark.parametrize("boundary", ["periodic"])  # zero-flux edges: test_continuum_sheet checks them on the chain
def test_final_fields_agree_with_pypde(boundary):
    p = Params(sigma=9 / 125, cells=N * N, shape=(N, N), lattice="square", boundary=boundary)
    # ours: ETDRK4 (the sheet's default), volumes = cells (points_per_cell 1), so the cell values are the volumes
    _, a, b = simulate_continuum(
        p, N * N, T_END, [], dt_out_s=T_END, points_per_cell=1, rtol=OURS_RTOL, atol=1e-12, initial=initial
    )
    grid = pde.CartesianGrid([(0.0, N), (0.0, N)], [N, N], periodic=boundary == "periodic")
    x, y = grid.cell_coords[..., 1], grid.cell_coords[..., 0]  # axis 0 runs down the rows (y), axis 1 along (x)
    a0, b0 = initial(x, y)
    state = pde.FieldCollection([pde.ScalarField(grid, a0), pde.ScalarField(grid, b0)])
    eq = SheetPDE(p, grid, "periodic" if boundary == "periodic" else {"derivative": 0})
    out = eq.solve(
        state,
        t_range=T_END,
        dt=1e-5,
        solver="runge-kutta",
        adaptive=True,
        tolerance=PYPDE_TOL,
        backend="numpy",
        tracker=None,
    )
    steps = eq.diagnostics["solver"]["steps"]
    pa, pb = out.data[0].ravel(), out.data[1].ravel()  # row-major = cell order
    assert np.abs(a0).max() > 1.0 and np.abs(a[-1] - a0.ravel()).max() > 0.3  # it moved, from the outer branch
    # the bound: py-pde's per-step error bound summed over its steps, plus ours (rtol 1e-8 of ~1 rad)
    bound = steps * PYPDE_TOL + 1e-7
    da, db = np.abs(a[-1] - pa), np.abs(b[-1] - pb)
    assert max(da.max(), db.max()) < bound
    assert np.sqrt(np.mean(da**2)) < bound / 3
