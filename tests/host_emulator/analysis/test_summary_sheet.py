"""summary.json of a sheet: the 2-D pattern measures, the chain-only keys null, domain_walls the boundary length; a
chain's summary keeps exactly its keys."""

import dataclasses
import json
import math

import numpy as np
import pytest

from host_emulator.analysis.observables import observables
from host_emulator.analysis.pattern2d import measures
from host_emulator.analysis.summary import CHAIN_ONLY_KEYS, SHEET_KEYS, clean, summarize
from host_emulator.result import RunResult
from host_emulator.scene import load_scene


def sheet_scene(lattice):
    sc = load_scene("default", ["model=lattice"])
    params = dataclasses.replace(sc.params, cells=256, shape=(16, 16), lattice=lattice)
    return dataclasses.replace(sc, cells=256, params=params)


def settling_stripes(topology):
    """A run whose stripes (wavelength 8, wavevector at 30 degrees) grow and settle by t = 0.5 s."""
    t = np.linspace(0, 1, 21)
    x = topology.positions()
    u = 0.6 * np.tanh(3 * np.cos(2 * math.pi / 8 * (x[:, 0] * math.cos(math.pi / 6) + x[:, 1] * 0.5)))
    alpha = np.minimum(t / 0.5, 1)[:, None] * u[None, :]
    return RunResult(t, alpha, 0.1 * alpha, 0.5, {})


@pytest.mark.parametrize("lattice", ["square", "hex"])
def test_a_sheets_summary_carries_the_pattern_measures(lattice):
    sc = sheet_scene(lattice)
    topo = sc.params.topology
    assert topo.is_sheet and topo.n == 256
    res = settling_stripes(topo)
    s = summarize(sc, res)
    json.dumps(s, allow_nan=False)  # JSON-ready
    want = measures(res.t, res.alpha, topo)
    assert {k: s[k] for k in SHEET_KEYS} == want
    assert s["pattern_kind"] == "stripes" and s["dominant_wavelength_cells"] == pytest.approx(8, rel=0.02)
    assert abs(s["orientation_deg"] - 30) < 1.0
    assert s["domain_walls"] == s["boundary_length_cells"] > 0
    assert all(s[k] is None for k in CHAIN_ONLY_KEYS)
    assert s["dispersion"] is None  # the chain's linear theory does not describe a sheet
    # what does not depend on the lattice stays
    obs = observables(res.t, res.alpha, res.beta)
    for k in ("steady", "at_rest", "oscillation_period_s", "amplitude_rad", "final_alpha_rad", "growth_rate_per_s"):
        assert s[k] == pytest.approx(obs[k])
    assert s["params"]["shape"] == [16, 16] and s["params"]["lattice"] == lattice


def test_a_chains_summary_has_no_sheet_keys():
    sc = load_scene("default", ["model=lattice"])
    t = np.linspace(0, 1, 11)
    alpha = np.tile(0.5 * np.cos(2 * math.pi * (np.arange(16) + 0.5) / 7.5), (11, 1))
    res = RunResult(t, alpha, 0.1 * alpha, 0.5, {})
    s = summarize(sc, res)
    obs = clean(observables(t, alpha, 0.1 * alpha))
    assert not set(SHEET_KEYS) & set(s)
    assert {k: s[k] for k in obs} == obs
    assert s["domain_walls"] == 4 and s["dispersion"] is not None
