"""`python -m host_emulator design` / he.design: targets and pushes, what counts as landing, a design verified by
running its own scene.toml, the Dask path, bad input and an unreachable target."""

import json
import tomllib

import numpy as np
import pytest

import host_emulator as he
from host_emulator.cli import main as emulator_main
from host_emulator.controller import run_scene
from host_emulator.models.options import RIG_UNCERTAINTY, rig_noise_overrides
from host_emulator.scene import load_scene, scene_table
from host_emulator.workbench import design as D
from metacell_tools.rigtools import command


def test_targets_parse_and_refuse_what_does_not_fit():
    t = D.parse_target("lambda=10")
    assert (t.kind, t.z, t.lam) == ("lambda", 3, 10.0)
    assert D.parse_target("lambda=7.5").z == 4 and D.parse_target("lambda=30").z == 1
    w = D.parse_target("walls=10.5,5.5", rest="")
    assert w.walls == (5.5, 10.5) and w.z == 2
    assert list(w.segments()) == [0] * 5 + [1] * 5 + [2] * 6
    r = D.parse_target("walls=2.5,5.5", rest="9-16")
    assert r.rest == tuple(range(9, 17)) and list(r.segments()) == [0, 0, 1, 1, 1, 2, 2, 2] + [3] * 8
    for bad, words in [
        ("lambda=8", ["3.75 walls do not fit", "7.5", "10"]),
        ("walls=5.4", ["bond j.5"]),
        ("walls=16.5", ["bond j.5"]),
        ("period=3", ["lambda=N"]),
    ]:
        with pytest.raises(D.DesignError) as e:
            D.parse_target(bad)
        assert all(x in str(e.value) for x in words), str(e.value)
    with pytest.raises(D.DesignError, match="rest cells lie outside"):
        D.parse_target("walls=8.5", rest="8-9")


def test_pushes_parse():
    assert D.parse_pushes("8") == (D.Push(8, 1),)
    assert D.parse_pushes("1:+,16:-") == (D.Push(1, 1), D.Push(16, -1))
    for bad in ("17", "8,8", "8:x", "a"):
        with pytest.raises(D.DesignError):
            D.parse_pushes(bad)


def test_landing_needs_the_walls_filled_domains_and_rest():
    t = D.parse_target("walls=5.5,10.5")
    good = np.array([-0.5] * 5 + [0.5] * 5 + [-0.5] * 6)
    assert D.lands(t, good)
    assert not D.lands(t, good, steady=False) and not D.lands(t, good, torque_ok=False)
    shifted = np.array([-0.5] * 4 + [0.5] * 6 + [-0.5] * 6)
    assert D.final_walls(shifted) == [4.5, 10.5] and not D.lands(t, shifted)
    bump = good.copy()
    bump[:3] = 0.05  # a bump on a chain partly at rest: no filled outer domain
    assert D.final_walls(bump) == [5.5, 10.5] and not D.lands(t, bump)
    weak = np.where(np.arange(16) >= 10, -0.2, good)  # a domain that never saturates
    assert not D.lands(t, weak)
    lam = D.parse_target("lambda=10")
    assert D.lands(lam, np.array([0.6] * 3 + [-0.6] * 5 + [0.6] * 5 + [-0.6] * 3))
    assert not D.lands(lam, good)
    assert D.miss_reason(t, good) is None and D.miss_reason(t, good, steady=False) == "moving"
    assert D.miss_reason(t, shifted) == "walls" and D.miss_reason(t, bump) == "domain not filled"
    assert D.miss_reason(t, good, torque_ok=False) == "torque limit" and D.miss_reason(t, 0 * good) == "at rest"
    half = D.parse_target("walls=2.5,5.5", rest="9-16")
    prof = np.array([0.5, 0.5, -0.5, -0.5, -0.5, 0.5, 0.5, 0.3] + [0.02] * 8)
    assert D.lands(half, prof) and not D.lands(half, np.where(np.arange(16) == 12, 0.3, prof))
    assert D.miss_reason(half, np.where(np.arange(16) == 12, 0.3, prof)) == "rest cells moved"


def test_linear_score_reads_the_chains_fastest_mode():
    from host_emulator.params import Params

    t = D.parse_target("lambda=10")
    score, facts = D.linear_score(Params(k_ab=0.03, k2=-0.06, sigma=0.0675), t)  # only mode m = 3 grows
    assert score > 1.9 and len(facts["walls"]) == 3 and facts["next_growth_per_s"] < 0
    score, facts = D.linear_score(Params(sigma=0.2), t)  # 14/125 and beyond: no stationary pattern
    assert score < 1


def test_design_lambda_10_push_8_verified_by_running_its_scene(tmp_path, capsys):
    rc = emulator_main(["design", "--target", "lambda=10", "--push", "8", "--seeds", "6", "--out", str(tmp_path)])
    assert rc == 0
    doc = json.loads((tmp_path / "design.json").read_text())
    assert doc["reached"] and doc["verification"]["fraction_seeds"] >= 0.9
    conf = doc["confirmation"]  # as many fresh draws, pooled with the verification's for `reached`
    assert conf["seeds"] == 6 and conf["pooled"] == (conf["fraction_seeds"] + doc["verification"]["fraction_seeds"]) / 2
    assert conf["pooled"] >= 0.9
    assert {"design.json", "scene.toml", "design.png"} <= {p.name for p in tmp_path.iterdir()}
    assert doc["linear_theory"]["score"] > 1 and doc["search"]["hil_runs"] >= 6
    # the scene as `run` loads it, with a noise seed the verification used: three walls (lambda = 10)
    sc = load_scene(str(tmp_path / "scene.toml"), D.noise_overrides(D.VERIFY_SEED0 + 1))
    assert sc.model == "hil" and [q.cell for q in sc.perturbations] == [8]
    assert sc.params.sigma == doc["params"]["sigma"]
    r = run_scene(sc, progress=False)
    assert len(D.final_walls(r.alpha[-1])) == 3
    assert doc["verification"]["runs"][1]["final_alpha_rad"] == [round(float(v), 4) for v in r.alpha[-1]]
    assert "lands in" in capsys.readouterr().out
    # the search held the firmware's configuration fixed: design.json names it, scene.toml writes it explicitly
    fw = doc["assumes"]["firmware"]
    assert fw["bemf_comp"] is False and fw["pwm_limit_ticks"] == 5860 * 2400 // 9000 and fw["pwm_top"] == 2400
    assert doc["assumes"]["model_options"]["stepper"] == sc.options.stepper == "symplectic_euler"
    written = tomllib.loads((tmp_path / "scene.toml").read_text())
    assert {k: written["params"][k] for k in ("bemf_comp", "pwm_top", "vmax_v", "control_rate_hz")} == {
        k: fw[k] for k in ("bemf_comp", "pwm_top", "vmax_v", "control_rate_hz")
    } and written["model_options"]["stepper"] == "symplectic_euler"
    assert command.design_config(str(tmp_path)) == {"bemf": 0, "pwm_limit": fw["pwm_limit_ticks"]}  # what apply checks
    # the second model: the same draws in the lattice, reported beside the hil's
    assert doc["cross_check"]["model"] == "lattice" and doc["cross_check"]["seeds"] == 6
    assert 0 <= doc["cross_check"]["fraction_seeds"] <= 1 and doc["verification"]["noise"] == RIG_UNCERTAINTY
    # reported as landing: so it does on fresh draws of the rig's uncertainty (seeds no search or check used)
    fresh = [scene_table(load_scene(str(tmp_path / "scene.toml"), rig_noise_overrides(9000 + s))) for s in range(10)]
    hits = [D.landing._landed(D.parse_target("lambda=10"), sc.params, r) for r in D.run_tables(fresh)]
    assert sum(hits) >= 9


def test_design_api_and_dask_give_the_runs_of_the_local_batch(tmp_path):
    from distributed import LocalCluster

    sc = load_scene("default", ["t_end_s=2"])
    tables = [D._noise(scene_table(sc), s) for s in (1, 2)]
    local = D.run_tables(tables)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        runner = D.Runner(cluster.scheduler_address)
        try:
            remote = runner(tables)
        finally:
            runner.close()
    assert remote == local and runner.runs == 2
    assert callable(he.design)


def test_bad_input_exits_2_and_an_unreachable_target_exits_3(tmp_path, capsys):
    assert emulator_main(["design", "--target", "lambda=8", "--out", str(tmp_path / "a")]) == 2
    assert "do not fit" in capsys.readouterr().err
    assert emulator_main(["design", "--target", "lambda=10", "--vary", "gamma", "--out", str(tmp_path / "b")]) == 2
    rc = emulator_main(
        ["design", "--target", "lambda=10", "--push", "8", "--vary", "k1", "--seeds", "2", "--search-seeds", "1"]
        + ["--maxiter", "0", "--no-nearest", "--out", str(tmp_path / "c")]
    )  # k1 alone cannot move the linear band: the source's law selects about 7.5 cells from this push
    doc = json.loads((tmp_path / "c" / "design.json").read_text())
    assert rc == 3 and not doc["reached"] and "NOT REACHED" in capsys.readouterr().out


def test_the_tables_wall_layouts_keep_their_spacing_and_repeat():
    from host_emulator.benchmarks.design_table import wall_layouts

    lays = wall_layouts(20)
    assert len(set(lays)) == 20 and lays == wall_layouts(20)
    for w in lays:
        assert 1 <= len(w) <= 4 and all(1.5 <= x <= 15.5 and x % 1 == 0.5 for x in w)
        assert all(b - a >= 3 for a, b in zip(w[:-1], w[1:]))
        D.parse_target("walls=" + ",".join(map(str, w)))  # every layout is a valid target
