"""metacell_tools.experiment's plan: scene -> wire values (independent arithmetic, hypothesis), what the rig
cannot set, the rehearsal server's overrides, cell lists as text."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from host_emulator.scene import list_scenes, load_scene
from metacell_tools.experiment.plan import PlanError, make_plan, perturb_payload, pwm_limit_ticks, wire_param
from metacell_tools.experiment.rehearse import serve_overrides
from metacell_tools.experiment.runner import cells_text
from metacell_tools.rigtools import proto
from protocol import codec

TMAX = codec.PERTURB_MAX_NM  # the firmware's limit (0.131 N*m)
LSB = codec.TORQUE_WIRE_UNM * 1e-6  # PERTURB torque LSB on the wire (4 uN*m)


@given(st.floats(-TMAX, TMAX), st.floats(0.0005, 30.0), st.sampled_from(["alpha", "beta"]))
def test_perturb_payload_round_trips_within_half_lsb(torque, duration, chain):
    p = perturb_payload(chain, torque, duration, 2000, "perturbation[1]")
    assert abs(p["torque"] * LSB - torque) <= LSB / 2 + 1e-12
    assert abs(p["ticks"] / 2000 - duration) <= 0.25e-3 + 1e-12 or p["ticks"] == 1
    assert p["chain"] == (0 if chain == "alpha" else 1)
    proto.pack_payload("PERTURB", **p)  # fits the wire layout


@given(st.one_of(st.floats(TMAX + LSB, 10), st.floats(-10, -TMAX - LSB)))
def test_perturb_torque_beyond_firmware_limit_is_refused(torque):
    with pytest.raises(PlanError, match="torque_Nm"):
        perturb_payload("alpha", torque, 0.1, 2000, "perturbation[1]")


def test_perturb_duration_beyond_u16_ticks_is_refused():
    with pytest.raises(PlanError, match="duration_s"):
        perturb_payload("alpha", 0.01, 65536 / 2000, 2000, "perturbation[2]")


@given(st.floats(-1e3, 1e3, allow_nan=False))
def test_wire_param_is_micro_units(v):
    assert wire_param("sigma", v) == round(v * 1e6)


@given(st.one_of(st.floats(2148, 1e30), st.floats(-1e30, -2148)))
def test_wire_param_beyond_the_int32_register_is_refused(v):
    with pytest.raises(PlanError, match="params.sigma"):
        wire_param("sigma", v)


def test_wire_param_refuses_non_finite():
    with pytest.raises(PlanError, match="params.sigma"):
        wire_param("sigma", math.inf)


@pytest.mark.parametrize("name", [n for n, _, _ in list_scenes() if load_scene(n).cells <= proto.N_CELLS])
def test_every_shipped_scene_has_a_rig_plan(name):
    sc = load_scene(name)
    plan = make_plan(sc)
    regs = [c.reg for c in plan.setup]
    assert regs[0] == "ENABLE" and plan.setup[0].values == {"on": 0}  # drive off before anything else
    assert {"K_AB", "SIGMA", "K1", "K2", "ASTAR", "PWM_LIMIT", "BEMF"} <= set(regs)
    assert next(c for c in plan.setup if c.reg == "SIGMA").values["value"] == round(sc.params.sigma * 1e6)
    assert len(plan.perturbations) == len(sc.perturbations)
    for c, q in zip(plan.perturbations, sorted(sc.perturbations, key=lambda q: (q.start_s, q.cell))):
        assert c.values["ticks"] == max(1, round(q.duration_s * 2000)) and c.cell == q.cell
    assert plan.last_perturbation_end_s == max([q.start_s + q.duration_s for q in sc.perturbations], default=0.0)


def test_plan_names_what_the_rig_cannot_set():
    plan = make_plan(load_scene("exp4_stable_eta10"))
    assert plan.not_settable.get("eta_scale") == 10.0
    assert "sigma" not in plan.not_settable
    assert pwm_limit_ticks(load_scene("default").params) == round(5.86 / 9 * 2400)


@pytest.mark.parametrize("name", [n for n, _, _ in list_scenes() if load_scene(n).cells > proto.N_CELLS])
def test_a_shipped_sheet_larger_than_the_rig_has_no_rig_plan(name):
    with pytest.raises(PlanError, match="cells"):
        make_plan(load_scene(name))


def test_plan_refuses_too_many_cells():
    with pytest.raises(PlanError, match="cells"):
        make_plan(load_scene("default", ["cells=20"]))


def test_serve_overrides_strip_pushes_and_reset_firmware_params():
    sc = load_scene("exp1_ccw_ccw", ["params.sigma=0.3"])
    o = serve_overrides(sc, ["params.sigma=0.3"])
    assert "perturbation.1.torque_Nm=0" in o and "perturbation.2.torque_Nm=0" in o and "model=hil" in o
    served = load_scene("exp1_ccw_ccw", o)
    assert all(q.torque_Nm == 0 for q in served.perturbations)
    assert served.params.sigma == pytest.approx(9 / 125)  # the runner must set sigma itself


def test_cells_text():
    assert cells_text([1, 2, 3, 5, 7, 8]) == "1-3, 5, 7, 8"
    assert cells_text([]) == ""
