"""The source paper's patterns at the rig's band stiffness: domain walls of the four pattern scenes in both
models, the bounded 14/125 limit cycle of the actuator-limited lattice, and the factor of two in the band law."""

import math

import numpy as np
import pytest

from host_emulator import params as P
from host_emulator.analysis.observables import observables
from host_emulator.analysis.stability import dispersion
from host_emulator.controller import run_scene
from host_emulator.models import ModelOptions, make_model
from host_emulator.params import Params
from host_emulator.scene import load_scene

# scene -> the source's wavelength (cells) and its domain walls Z = 30 / lambda
PATTERNS = {"exp1_ccw_ccw": 2, "exp2_ccw_cw": 3, "exp3_single_sigma9": 4, "exp3_single_sigma6": 2}


def summary_of(name, *sets):
    scene = load_scene(name, list(sets))
    res = run_scene(scene, progress=False)
    return observables(res.t, res.alpha, res.beta)


@pytest.mark.parametrize("model", ["hil", "lattice"])
@pytest.mark.parametrize("name", sorted(PATTERNS))
def test_pattern_scenes_select_the_sources_domain_walls(name, model):
    o = summary_of(name, f"model={model}")
    assert o["steady"] and not o["at_rest"]
    assert o["domain_walls"] == PATTERNS[name]
    assert o["pattern_wavelength_cells"] == pytest.approx(30 / PATTERNS[name])


def test_sigma14_lattice_is_a_bounded_uniform_limit_cycle_and_eta10_returns_to_rest():
    """Inertia at eta x1 makes the uniform mode grow (+38.9/s, period 0.029 s); the actuators' torque limit
    bounds it into a steady oscillation at the linear period. With eta x10 everything decays."""
    theory = dispersion(Params(sigma=14 / 125), inertia=True)
    assert theory["uniform_mode_growth_per_s"] > 0
    o = summary_of("exp3_single_sigma14", "model=lattice")
    assert o["oscillation_period_s"] == pytest.approx(0.029, abs=0.002)
    assert o["oscillation_period_s"] == pytest.approx(theory["uniform_mode_period_s"], rel=0.05)
    assert o["dominant_mode"] == 0  # spatially uniform
    fa = np.array(o["final_alpha_rad"])
    assert np.ptp(fa) < 0.05 * np.abs(fa).max()
    assert 0.05 < o["amplitude_rad"] < 3.0  # bounded, not decayed
    o10 = summary_of("exp3_single_sigma14", "model=lattice", "params.eta_scale=10")
    assert o10["at_rest"] and o10["oscillation_period_s"] is None


def test_without_the_actuator_limit_sigma14_grows_until_the_run_stops():
    from host_emulator.models import NumericalInstability

    with pytest.raises(NumericalInstability):
        run_scene(load_scene("exp3_single_sigma14", ["model=lattice", "params.actuator_limit=false"]), progress=False)


@pytest.mark.parametrize("band_scale", [0.5, 1.0])
def test_band_law_slope_is_twice_band_scale_times_the_table_k(band_scale):
    """The simulated cubic band law's small-deflection stiffness, measured on the compiled plant, equals
    2 * band_scale * (r^2 f'(delta0)) and so 2 * band_scale * the table k (which is r^2 f' to 0.2 %)."""
    p = Params(cells=2, band_scale=band_scale, k_ab=0.0, k1=0.0, k2=0.0, sigma=0.0, alpha_star=0.0)
    m = make_model("lattice", p, [], ModelOptions())
    eps = 1e-6
    for ch, (k_eff, r, coef, d0) in enumerate(
        ((p.ka_eff, P.R_ALPHA_M, P.BAND_A_COEF, P.DELTA_A0_M), (p.kb_eff, P.R_BETA_ARM_M, P.BAND_B_COEF, P.DELTA_B0_M))
    ):
        x = np.zeros(4)
        x[2 * ch] = eps
        F, _ = m.forces(0.0, x)
        slope = -F[2 * ch] / eps
        assert slope == pytest.approx(2 * band_scale * r * r * P.band_slope(coef, d0), rel=1e-4)
        assert slope == pytest.approx(k_eff, rel=2e-3)


def test_dispersion_at_table_k_and_at_the_rigs_k():
    """band_scale 0.5 gives the source's stability figure (fastest 6.83 cells, band 3.84-15.19); the default
    (the rig's pair of bands) fastest 9.84, band 5.79-21.56, which contains the observed 15, 10 and 7.5."""
    table = dispersion(Params(band_scale=0.5))
    rig = dispersion(Params())
    assert table["fastest_lambda_cells"] == pytest.approx(6.83, abs=0.01)
    assert table["unstable_set_cells"] == [pytest.approx([3.84, 15.19], abs=0.01)]
    assert rig["fastest_lambda_cells"] == pytest.approx(9.84, abs=0.01)
    assert rig["unstable_set_cells"] == [pytest.approx([5.79, 21.56], abs=0.01)]
    for lam in (15, 10, 7.5):
        assert rig["unstable_set_cells"][0][0] < lam < rig["unstable_set_cells"][0][1]
    # the growth rate depends on stiffness only through q*k, so the same rate sits at a longer wave
    assert rig["fastest_growth_per_s"] == pytest.approx(table["fastest_growth_per_s"], rel=1e-6)
    assert math.isclose(
        2 * (1 - math.cos(table["fastest_kappa"])), 2 * 2 * (1 - math.cos(rig["fastest_kappa"])), rel_tol=1e-5
    )
