"""The model registry and the Solver base class: models by name, one construction path, no duck typing."""

import numpy as np
import pytest

from host_emulator import controller, models
from host_emulator.models import ConfigError, Solver, make_model, model_class, model_names, register_model
from host_emulator.params import Params
from host_emulator.scene import load_scene


def test_registered_models_and_their_solvers_share_the_base_class():
    assert set(model_names()) >= {"continuum", "lattice", "hil"}
    p = Params(cells=4)
    for name in ("lattice", "hil", "continuum"):
        s = make_model(name, p).solver()
        assert isinstance(s, Solver)
        assert s.whole_run == (name == "continuum")
        assert (s.faults() is None) == (name != "hil")


def test_unknown_model_and_double_registration_are_refused():
    with pytest.raises(ConfigError, match="expected one of"):
        make_model("nope", Params())
    with pytest.raises(ValueError, match="registered twice"):
        register_model("lattice", object)


def test_a_registered_model_runs_through_the_controller():
    """A new model needs only register_model: a stepping Solver subclass gets advance_many from the base."""

    class Decay(Solver):
        def __init__(self, model):
            self.model, self.dt_out, self.t, self.x = model, 0.1, 0.0, np.ones(2 * model.n)

        def state(self):
            n = self.model.n
            return self.x[:n].copy(), self.x[n:].copy()

        def advance(self):
            self.x *= 0.5
            self.t += self.dt_out

    class DecayModel:
        name = "decay_test"

        def __init__(self, params, perturbations=(), options=None):
            self.n = params.cells

        def solver(self, x0=None):
            return Decay(self)

    register_model("decay_test", DecayModel)
    try:
        assert model_class("decay_test") is DecayModel
        res = controller.run_solver(make_model("decay_test", Params(cells=3)).solver(), 0.3)
    finally:
        models._REGISTRY.pop("decay_test")
    assert np.allclose(res.alpha[:, 0], [1.0, 0.5, 0.25, 0.125])


def test_build_solver_is_what_run_scene_runs():
    """run_scene and the bus rig use controller.build_solver: the scene's accuracy preset is applied."""
    from host_emulator.bus.rig import make_rig

    sc = load_scene("default", ["t_end_s=0.05"])
    s = controller.build_solver(sc)
    rig, _ = make_rig("default", overrides=["t_end_s=0.05"])
    assert rig.solver.info()["substeps_per_tick"] == s.info()["substeps_per_tick"]
    raw = controller.build_solver(sc, resolve=False)
    assert raw.info()["dt_s"] > 0
    res = controller.run_scene(sc, progress=False)
    assert np.array_equal(res.alpha[-1], controller.run_solver(controller.build_solver(sc), sc.t_end_s).alpha[-1])
