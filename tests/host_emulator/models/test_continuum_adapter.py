"""The continuum model behind the controller: same output contract as lattice/hil, and it agrees with them at rest."""

import numpy as np

from host_emulator.controller import run_scene
from host_emulator.scene import load_scene


def test_continuum_scene_runs_through_the_controller():
    sc = load_scene("continuum_single", ["t_end_s=1"])
    res = run_scene(sc, progress=False)
    assert res.alpha.shape == res.beta.shape == (101, 16)
    assert np.all(np.isfinite(res.alpha)) and np.abs(res.alpha).max() > 0.1
    rest = run_scene(load_scene("continuum_single", ["t_end_s=0.5", "perturbation.1.torque_Nm=0"]), progress=False)
    assert np.abs(rest.alpha).max() == 0
