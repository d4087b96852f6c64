"""The rig's uncertainty as noise options ([model_options.noise] inertia_spread, push_spread, push_timing_s,
distribution): the draws, their bounds, and that lattice, hil and continuum take them alike."""

import dataclasses

import numpy as np
import pytest

from host_emulator.controller import run_scene
from host_emulator.models import ConfigError, make_model
from host_emulator.models.continuum import _laplacian, _laplacian_weighted
from host_emulator.models.options import RIG_UNCERTAINTY, ModelOptions, NoiseOptions, parse_noise, rig_noise_overrides
from host_emulator.models.plant import draw_rig, spreads
from host_emulator.params import Params
from host_emulator.scene import load_scene

RIG = NoiseOptions(**RIG_UNCERTAINTY)


def test_the_rig_ensemble_draws_stay_in_their_ranges_and_differ_by_seed():
    sc = load_scene("exp1_ccw_ccw", ["model=lattice"])
    seen = set()
    for seed in range(40):
        o = ModelOptions(noise=dataclasses.replace(RIG, seed=seed))
        p, q = draw_rig(sc.params, sc.perturbations, o)
        band, eta = spreads(sc.params, o, 16)
        assert np.all((band[:, :15] >= 0.85) & (band[:, :15] <= 1.15)) and np.all(band[:, 15] == 1)
        assert np.all((eta[0] >= 0.7) & (eta[0] <= 1.3)) and np.all(eta[1] == 1)
        assert 0.9 <= p.I_a / sc.params.I_a <= 1.1 and 0.9 <= p.I_b / sc.params.I_b <= 1.1
        for a, b in zip(sc.perturbations, q):
            assert 0.7 <= b.torque_Nm / a.torque_Nm <= 1.3 and abs(b.start_s - a.start_s) <= 0.05 + 1e-12
            assert b.duration_s == a.duration_s and b.cell == a.cell
        seen.add(round(q[0].torque_Nm, 9))
    assert len(seen) == 40


def test_without_the_new_spreads_nothing_is_drawn_and_the_band_draws_stay_what_they_were():
    sc = load_scene("exp1_ccw_ccw", ["model=lattice"])
    o = ModelOptions(noise=NoiseOptions(seed=3, band_spread=0.05, eta_spread=0.05))
    p, q = draw_rig(sc.params, sc.perturbations, o)
    assert p is sc.params and q is sc.perturbations
    more = ModelOptions(noise=dataclasses.replace(o.noise, push_spread=0.3, inertia_spread=0.1))
    assert all(np.array_equal(a, b) for a, b in zip(spreads(sc.params, o, 16), spreads(sc.params, more, 16)))


@pytest.mark.parametrize("model", ["lattice", "hil"])
def test_a_drawn_push_and_inertia_run_as_the_same_values_written_into_the_scene(model):
    base = [f"model={model}", "t_end_s=1"]
    noisy = load_scene("exp1_ccw_ccw", base + rig_noise_overrides(7))
    p, q = draw_rig(noisy.params, noisy.perturbations, noisy.options)
    sets = [f"params.I_a={p.I_a!r}", f"params.I_b={p.I_b!r}"]
    for i, x in enumerate(q, start=1):
        sets += [f"perturbation.{i}.torque_Nm={x.torque_Nm!r}", f"perturbation.{i}.start_s={x.start_s!r}"]
    band_eta = [f"model_options.noise.{k}={RIG_UNCERTAINTY[k]}" for k in ("band_spread", "eta_spread")]
    spelled = load_scene(
        "exp1_ccw_ccw",
        base + sets + ["model_options.noise.seed=7", "model_options.noise.distribution=uniform"] + band_eta,
    )
    a, b = run_scene(noisy, progress=False), run_scene(spelled, progress=False)
    assert np.array_equal(a.alpha, b.alpha) and np.array_equal(a.beta, b.beta)
    assert not np.array_equal(a.alpha, run_scene(load_scene("exp1_ccw_ccw", base), progress=False).alpha)


def test_the_continuum_takes_the_band_and_viscosity_draws():
    assert np.array_equal(_laplacian(12, 0.25).toarray(), _laplacian_weighted(12, 0.25, np.ones(11)).toarray())
    base = ["model=continuum", "t_end_s=2"]
    plain = run_scene(load_scene("default", base), progress=False)
    ones = ["model_options.noise.band_spread=1e-300", "model_options.noise.eta_spread=1e-300"]
    assert np.allclose(run_scene(load_scene("default", base + ones), progress=False).alpha, plain.alpha, atol=1e-9)
    rig = run_scene(load_scene("default", base + rig_noise_overrides(2)), progress=False)
    assert np.abs(rig.alpha[-1] - plain.alpha[-1]).max() > 0.01
    m = make_model("continuum", Params(), [], ModelOptions(noise=dataclasses.replace(RIG, seed=2)))
    assert m.params.I_a != Params().I_a  # the inertia draw reaches every model's params (the continuum has none)


def test_a_bad_distribution_is_a_one_line_error_naming_the_key():
    with pytest.raises(ConfigError) as e:
        parse_noise({"distribution": "gauss"})
    assert "model_options.noise.distribution" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ConfigError):
        parse_noise({"push_timing_s": -0.1})
