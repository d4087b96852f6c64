"""Golden trajectories: SHA-256 of the raw float64 bytes (alpha, beta, t) of short pinned runs.

Speed work on the compiled loop (compiler flags, loop restructuring, batching) must not change a single bit
of any trajectory; these hashes prove it. Every physics parameter and every model option that affects the
result is pinned here, so a change of a default elsewhere does not move them. A hash changes only when the
simulated physics or the firmware's arithmetic changes on purpose: then re-run this file as a script
(`.venv/bin/python tests/host_emulator/test_golden.py`) and paste the new digests, saying why in the commit.

The bemf-on case runs the firmware's back-EMF compensation path, so a deliberate change to that path moves
its digest (and only its digest).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from host_emulator.controller import run_scene
from host_emulator.scene import scene_from_dict

# every Params field, as literals (the defaults may move; these must not)
PINNED_PARAMS = {
    "k_ab": 0.02,
    "k1": 0.06,
    "k2": -0.06,
    "alpha_star": 3 * math.pi / 8,
    "sigma": 0.072,
    "I_a": 6.39e-7,
    "I_b": 3.13e-7,
    "eta_a": 4.18e-4,
    "gamma": 0.1,
    "eta_scale": 1.0,
    "k_a": 1.46e-2,
    "k_b": 4.57e-2,
    "band_scale": 0.5,
    "slack_f0": True,
    "supply_v": 9.0,
    "vmax_v": 5.86,
    "kt": 0.09 / 12.0,
    "speed_const": 49.8,
    "control_rate_hz": 2000.0,
    "pwm_top": 2400,
    "bemf_comp": False,
}
HIL_OPTIONS = {
    "inertia": True,
    "bands": "cubic",
    "beta_geometry": "small",
    "stepper": "symplectic_euler",
    "substeps": 1,
    "dt_out": 0.01,
    "perturb_via": "plant",
}
LATTICE_OPTIONS = {
    "inertia": True,
    "bands": "cubic",
    "beta_geometry": "small",
    "stepper": "rk4",
    "dt": 5e-4,
    "dt_out": 0.01,
}
PUSH = {"cell": 8, "chain": "alpha", "torque_Nm": 0.02, "start_s": 0.1, "duration_s": 0.1}


def _scene(name, model, t_end, params=(), options=(), perturbation=(PUSH,)):
    opts = dict(HIL_OPTIONS if model == "hil" else LATTICE_OPTIONS)
    opts.update(options)
    return scene_from_dict(
        {
            "name": name,
            "model": model,
            "cells": 16,
            "t_end_s": t_end,
            "accuracy": "balanced",
            "params": {**PINNED_PARAMS, **dict(params)},
            "model_options": opts,
            "perturbation": [dict(p) for p in perturbation],
        }
    )


CASES = {
    "hil_default": lambda: _scene("hil_default", "hil", 1.0),
    "hil_noise": lambda: _scene(
        "hil_noise",
        "hil",
        1.0,
        options={
            "noise": {
                "seed": 7,
                "band_spread": 0.05,
                "eta_spread": 0.05,
                "encoder_jitter_counts": 0.4,
                "encoder_glitch_prob": 1e-3,
            }
        },
    ),
    "hil_bemf": lambda: _scene("hil_bemf", "hil", 1.0, params={"bemf_comp": True}),
    "hil_firmware_push": lambda: _scene(
        "hil_firmware_push",
        "hil",
        1.0,
        options={"perturb_via": "firmware"},
        perturbation=(PUSH, {"cell": 3, "chain": "beta", "torque_Nm": -0.01, "start_s": 0.305, "duration_s": 0.0505}),
    ),
    "lattice": lambda: _scene("lattice", "lattice", 1.0),
}

GOLDEN = {
    "hil_bemf": "bce619dff1addc2a4e514a9846c0c4acb6e50510d8f39f4f0c9ff377ffe590ce",
    "hil_default": "5d0f5e9f526a359b3fd60446a848c0d1f17c7506ec12bf08e676af0c1973892b",
    "hil_firmware_push": "1875f375e61d06ad9200679ca9666bb89506d4695ee83736e7c31f3b89518fc2",
    "hil_noise": "2e8e60d16a576fc6999f4ef2b0abfaeff8004f6dcee9e648d6dfa05abb8397de",
    "lattice": "2f34a7607669937b104af173572770dc4904954d674bd4f98e9e0fe8b61efda8",
}


def digest(res) -> str:
    h = hashlib.sha256()
    for arr in (res.alpha, res.beta, res.t):
        h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
    return h.hexdigest()


def run_case(name):
    return run_scene(CASES[name](), progress=False)


@pytest.mark.parametrize("name", sorted(CASES))
def test_golden_trajectory(name):
    res = run_case(name)
    assert np.all(np.isfinite(res.alpha)) and np.all(np.isfinite(res.beta))
    assert np.max(np.abs(res.alpha)) > 1e-3, "the push must move something, or the hash proves little"
    assert digest(res) == GOLDEN[name]


if __name__ == "__main__":
    for n in sorted(CASES):
        print(f'    "{n}": "{digest(run_case(n))}",')


@pytest.mark.parametrize("where", [0, 3, 14, 16 + 7, 31])
def test_fast_hil_step_reports_what_the_generic_step_reports(where):
    """The hil loop's one-pass plant step returns the code and time he_advance would, wherever the bad entry."""
    from host_emulator.models import make_model

    base = CASES["hil_default"]()
    cases = {"DIVERGED": (2000.0, None), "NONFINITE": (float("nan"), None), "BAND": (3.0, -3.0)}
    for code, (val, nb) in cases.items():
        got = []
        for generic in (False, True):
            # a perturbation of 0 N*m that is always on sends every step through he_advance
            m = make_model("hil", base.params, (), base.options)
            if generic:
                m.plant.npert = 1
                m.plant.pert[0].cell, m.plant.pert[0].chain, m.plant.pert[0].torque = 0, 0, 0.0
                m.plant.pert[0].t0, m.plant.pert[0].t1 = -1.0, 1e9
            s = m.solver()
            lib = m.lib
            s.x[where] = val
            if nb is not None:
                s.x[where + 1 if where % 16 != 15 else where - 1] = nb
            s._pt[0] = 0.0
            rc = lib.he_hil_run(s.h, 3, s._pt, s._px, s._pv)
            got.append((rc, s._pt[0]))
        assert got[0] == got[1], code
        assert got[0][0] == getattr(lib, f"HE_ERR_{code}")


def test_fast_hil_step_is_bit_identical_to_the_generic_step():
    """The hil default's one-pass plant step against he_advance (forced by a 0 N*m perturbation that is always
    on): a force term added to the generic plant but not to the fast step shows up here."""
    from host_emulator.controller import run_solver
    from host_emulator.models import make_model

    sc = _scene("fast_vs_generic", "hil", 0.5, options={"noise": {"seed": 2, "band_spread": 0.05, "eta_spread": 0.05}})
    out = []
    for generic in (False, True):
        m = make_model("hil", sc.params, sc.perturbations, sc.options)
        if generic:
            k = m.plant.npert
            m.plant.npert = k + 1
            m.plant.pert[k].cell, m.plant.pert[k].chain, m.plant.pert[k].torque = 0, 0, 0.0
            m.plant.pert[k].t0, m.plant.pert[k].t1 = -1.0, 1e9
        out.append(run_solver(m.solver(), sc.t_end_s))
    assert np.max(np.abs(out[0].alpha)) > 1e-3
    assert np.array_equal(out[0].alpha, out[1].alpha) and np.array_equal(out[0].beta, out[1].beta)
