"""run_batch: one compiled call for many hil lattices, bit-identical per point to run_scene."""

from __future__ import annotations

import numpy as np
import pytest

from host_emulator.benchmarks.batch import sweep_scenes
from host_emulator.controller import run_scene
from host_emulator.scene import load_scene
from host_emulator.workbench.batch import run_batch


def _same(a, b):
    assert np.array_equal(a.t, b.t) and a.t.dtype == b.t.dtype
    assert np.array_equal(a.alpha, b.alpha) and np.array_equal(a.beta, b.beta)


def test_batch_matches_run_scene_per_point():
    scenes = sweep_scenes(4, 0.6)
    scenes.append(
        load_scene(
            "default",
            [
                "t_end_s=0.6",
                "model_options.noise.encoder_jitter_counts=0.3",
                "model_options.noise.encoder_glitch_prob=0.01",
                "model_options.noise.seed=3",
            ],
        )
    )
    # firmware perturbation commands and a lattice scene take the run_scene path inside the same call
    scenes.append(load_scene("default", ["t_end_s=0.6", "model_options.perturb_via=firmware"]))
    scenes.append(load_scene("default", ["t_end_s=0.3", "model=lattice"]))
    got = run_batch(scenes)
    for s, g in zip(scenes, got):
        ref = run_scene(s, progress=False)
        _same(ref, g)
        assert np.max(np.abs(ref.alpha)) > 1e-4
    assert got[0].info["batch_wall_s"] > 0 and len(got[0].info["cell_faults"]) == 16
    # points are independent: the order of the batch changes nothing
    _same(run_batch(scenes[:4][::-1])[0], got[3])


def test_batch_keep_final():
    scenes = sweep_scenes(3, 0.4)
    full = run_batch(scenes)
    fin = run_batch(scenes, keep="final")
    for f, g in zip(full, fin):
        assert fin and g.t.shape == (1,) and g.t[0] == f.t[-1]
        assert np.array_equal(g.alpha[0], f.alpha[-1]) and np.array_equal(g.beta[0], f.beta[-1])


def test_batch_bad_arguments():
    with pytest.raises(ValueError, match="keep"):
        run_batch([], keep="some")
    with pytest.raises(ValueError, match="errors"):
        run_batch([], errors="ignore")
    assert run_batch([]) == []
