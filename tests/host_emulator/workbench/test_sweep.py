"""Sweeps on Dask: grid parsing, a local cluster, resume, failures recorded, an external scheduler + 2 workers,
and a worker killed mid-sweep (its points are retried or recorded as failed, never lost)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")
xr = pytest.importorskip("xarray")

from host_emulator.workbench.sweep import SweepError, evaluate_points, parse_grid, point_specs, sweep  # noqa: E402

BIN = Path(sys.executable).parent


def test_parse_grid():
    k, v = parse_grid("params.sigma=0.04:0.12:41")
    assert k == "params.sigma" and len(v) == 41 and v[0] == 0.04 and v[-1] == 0.12
    assert np.allclose(np.diff(v), 0.002)
    # exact values: each the float nearest the decimal, so ds.sel(sigma=0.056) finds it (linspace: 0.0559999...)
    assert v[8] == 0.056 and np.linspace(0.04, 0.12, 41)[8] != 0.056
    assert [repr(x) for x in v[:4]] == ["0.04", "0.042", "0.044", "0.046"]
    assert parse_grid("params.sigma=6/125:14/125:3")[1] == [6 / 125, 10 / 125, 14 / 125]
    assert parse_grid("perturbation.1.torque_Nm=0.005,0.01,0.02,0.04") == (
        "perturbation.1.torque_Nm",
        [0.005, 0.01, 0.02, 0.04],
    )
    assert parse_grid("params.sigma=9/125,6/125")[1] == [9 / 125, 6 / 125]
    for bad in ("params.sigma", "params.sigma=", "params.sigma=1:2:x", "params.sigma=1:2:0", "a=1,1"):
        with pytest.raises(SweepError):
            parse_grid(bad)


def test_point_specs_and_evaluate_points_records_failures():
    specs, axes = point_specs("default", {"params.eta_a": [4.18e-4, -1.0]}, 2, ["t_end_s=0.3"])
    assert len(specs) == 4 and axes["seed"] == [0, 1]
    assert specs[3]["overrides"] == ["t_end_s=0.3", "params.eta_a=-1.0", "model_options.noise.seed=1"]
    res = evaluate_points(specs)
    assert [r["index"] for r in res] == [0, 1, 2, 3]
    assert [r["status"] for r in res] == ["ok", "ok", "failed", "failed"]
    assert "eta_a" in res[2]["error"] and "ConfigError" in res[2]["error"]
    assert res[0]["regime"] and np.isfinite(res[0]["amplitude_rad"])


def test_local_cluster_sweep_dataset_resume_and_failures(tmp_path):
    out = tmp_path / "sw"
    grid = {"params.sigma": [0.05, 0.09], "params.eta_a": [4.18e-4, -1.0]}
    ds = sweep("default", grid, seeds=2, out=out, fixed=["t_end_s=0.5"], workers=2, progress=False)
    assert ds["pattern_wavelength_cells"].dims == ("sigma", "eta_a", "seed")
    assert ds["sigma"].attrs["key"] == "params.sigma" and ds["eta_a"].attrs["key"] == "params.eta_a"
    st = ds["status"].values.astype(str)
    assert (st[:, 0] == "ok").all() and (st[:, 1] == "failed").all()  # failed points kept, with reasons
    assert all("eta_a" in e for e in ds["error"].values[:, 1].ravel().astype(str))
    assert ds.attrs["sweep.failed"] == 4 and ds.attrs["provenance.git_describe"]
    assert set(ds["regime"].values[:, 0].ravel().astype(str)) == {"broadband_pattern", "stationary_pattern"}
    back = xr.open_dataset(out / "sweep.nc", engine="scipy")
    np.testing.assert_array_equal(back["amplitude_rad"].values, ds["amplitude_rad"].values)
    assert back.attrs["provenance.firmware_build"] == ds.attrs["provenance.firmware_build"]
    assert (out / "phase_diagram.png").exists() and (out / "regime_map.png").exists()
    # the theory band drawn for sigma = 0.09 is the dispersion's own
    from host_emulator.analysis.stability import dispersion
    from host_emulator.analysis.summary import theory_for
    from host_emulator.scene import load_scene

    sc = load_scene("default", ["params.sigma=0.09"])
    d = dispersion(sc.params, theory=theory_for(sc), n_cells=16)
    point = ds.sel(sigma=0.09, eta_a=4.18e-4, seed=0)
    assert point["theory_band_lo_cells"].values[0] == pytest.approx(d["unstable_set_cells"][0][0])
    assert str(point["theory_band_kind"].values[0]) == "stationary"
    assert (ds["regime"].sel(sigma=0.09, eta_a=4.18e-4).values.astype(str) == d["regime"]).all()
    # resumable: a re-run evaluates nothing new (no cluster needed: every point is done)
    n_lines = len((out / "points.jsonl").read_text().splitlines())
    ds2 = sweep("default", grid, seeds=2, out=out, fixed=["t_end_s=0.5"], workers=2, progress=False, plots=False)
    assert len((out / "points.jsonl").read_text().splitlines()) == n_lines
    np.testing.assert_array_equal(ds2["amplitude_rad"].values, ds["amplitude_rad"].values)
    # a different sweep into the same directory is refused
    with pytest.raises(SweepError, match="different sweep"):
        sweep("default", {"params.sigma": [0.05]}, out=out, fixed=["t_end_s=0.5"], progress=False)


def test_resume_after_a_partial_run(tmp_path):
    """Points already in points.jsonl are not run again; a cut last line is run again."""
    out = tmp_path / "sw"
    grid = {"params.sigma": [0.05, 0.07, 0.09]}
    specs, _ = point_specs("default", grid, None, ["t_end_s=0.3"])
    out.mkdir()
    first = evaluate_points(specs[:1])
    first[0]["amplitude_rad"] = 123.0  # a marker: must survive the resume untouched
    (out / "points.jsonl").write_text(json.dumps(first[0]) + "\n" + '{"index": 1, "sta')
    ds = sweep("default", grid, out=out, fixed=["t_end_s=0.3"], workers=1, progress=False, plots=False)
    assert ds["amplitude_rad"].values[0] == 123.0
    assert list(ds["status"].values.astype(str)) == ["ok", "ok", "ok"]


def test_cli_sweep_bad_grid_is_exit_2(capsys):
    from host_emulator.cli import main

    assert main(["sweep", "default", "--grid", "params.sigmaa=0.1,0.2", "--out", "/tmp/never-written-i11"]) == 2
    assert "sigmaa" in capsys.readouterr().err
    assert not Path("/tmp/never-written-i11").exists()


def _start_cluster(tmp_path, n_workers=2):
    sf = tmp_path / "scheduler.json"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[3]))
    procs = [
        subprocess.Popen(
            [str(BIN / "dask"), "scheduler", "--port", "0", "--no-dashboard", "--scheduler-file", str(sf)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    ]
    t0 = time.time()
    while not sf.exists() and time.time() - t0 < 300:  # event-driven; the bound only for a badly loaded machine
        time.sleep(0.1)
    assert sf.exists(), "the Dask scheduler wrote no scheduler file in 300 s"
    addr = json.loads(sf.read_text())["address"]
    for _ in range(n_workers):
        procs.append(
            subprocess.Popen(
                [str(BIN / "dask"), "worker", addr, "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env=env,
            )
        )
    from distributed import Client

    with Client(addr, timeout="30s") as c:
        c.wait_for_workers(n_workers, timeout=300)
    return addr, procs


def _stop(procs):
    for p in procs[::-1]:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()


def test_external_scheduler_and_a_worker_killed_mid_sweep(tmp_path):
    """The CLI against `dask scheduler` + 2 `dask worker` processes; one worker is killed while the sweep runs:
    every point ends ok (retried on the survivor) or failed with its reason; none is pending."""
    addr, procs = _start_cluster(tmp_path)
    try:
        out = tmp_path / "ext"
        cmd = [
            sys.executable,
            "-m",
            "host_emulator",
            "sweep",
            "default",
            "--grid",
            "params.sigma=0.05:0.09:12",
            "--seeds",
            "2",
            "--set",
            "t_end_s=8",
            "--chunk",
            "1",
            "--scheduler",
            addr,
            "--out",
            str(out),
            "--no-plots",
            "--quiet",
        ]
        sw = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t0 = time.time()
        pts = out / "points.jsonl"
        while time.time() - t0 < 300 and (not pts.exists() or len(pts.read_text().splitlines()) < 3):
            time.sleep(0.05)
        assert pts.exists() and len(pts.read_text().splitlines()) >= 3, "no 3 points finished in 300 s"
        victim = procs[1]
        victim.send_signal(signal.SIGKILL)
        killed_at = len(pts.read_text().splitlines())
        so, se = sw.communicate(timeout=900)
        assert sw.returncode in (0, 1), se
        ds = xr.open_dataset(out / "sweep.nc", engine="scipy")
        st = ds["status"].values.astype(str).ravel()
        assert st.size == 24 and "pending" not in st
        err = ds["error"].values.astype(str).ravel()
        assert all(e for s, e in zip(st, err) if s == "failed")
        assert killed_at < 24  # the kill did land mid-sweep
        assert ds.attrs["provenance.command"].find("sweep") >= 0
    finally:
        _stop(procs)


def test_api_sweep_takes_what_run_takes_and_runs_twice(tmp_path):
    """A notebook re-runs its cells: he.sweep stays the function; a Scene object, a dict of overrides with a
    fraction, string grid values and accuracy= are accepted as by he.run; coordinates are plain and .sel-able."""
    import host_emulator as he
    from host_emulator.workbench.api import load_scene

    sc = load_scene("default", {"t_end_s": 0.3})
    for i in range(2):
        ds = he.sweep(
            sc,
            {"params.sigma": ["6/125", 0.072]},
            fixed={"params.eta_scale": "3/2"},
            accuracy="fast",
            out=tmp_path / f"s{i}",
            workers=1,
            progress=False,
            plots=False,
        )
        assert callable(he.sweep)
    assert list(ds["sigma"].values) == [0.048, 0.072]
    assert ds.attrs["params.eta_scale"] == 1.5 and ds.attrs["accuracy"] == "fast" and ds.attrs["t_end_s"] == 0.3
    assert str(ds.sel(sigma=0.048)["status"].values) == "ok"
    assert ds.attrs["source"] == "emulator:hil"


def test_bare_key_gets_a_hint(tmp_path):
    from host_emulator.models import ConfigError

    with pytest.raises(ConfigError, match=r"did you mean params\.sigma"):
        sweep("default", {"sigma": [0.05]}, out=tmp_path / "x", progress=False)
    assert not (tmp_path / "x").exists()


def test_coordinate_names():
    from host_emulator.workbench.sweep import coord_names

    assert coord_names(["params.sigma", "perturbation.1.torque_Nm", "seed"]) == {
        "params.sigma": "sigma",
        "perturbation.1.torque_Nm": "torque_Nm",
        "seed": "seed",
    }
    both = coord_names(["perturbation.1.torque_Nm", "perturbation.2.torque_Nm", "model_options.noise.seed"])
    assert both == {
        "perturbation.1.torque_Nm": "perturbation_1_torque_Nm",
        "perturbation.2.torque_Nm": "perturbation_2_torque_Nm",
        "model_options.noise.seed": "model_options_noise_seed",
    }


def test_a_sweep_over_sigma_on_the_16x16_sheet(tmp_path):
    """A sweep takes a sheet scene as any other: every point runs, the dataset records the topology, and the phase
    diagram draws (its wavelength axis from the sheet's longer side: int() of the [rows, cols] attribute failed)."""
    import host_emulator as he

    ds = he.sweep(
        "sheet_16x16",
        {"params.sigma": [0.048, 0.072]},
        fixed={"t_end_s": 0.3},
        out=tmp_path / "s",
        workers=1,
        progress=False,
        plots=True,
    )
    assert [str(v) for v in ds["status"].values] == ["ok", "ok"]
    assert list(ds.attrs["topology.cells"]) == [16, 16] and ds.attrs["topology.lattice"] == "square"
    assert sorted(p.name for p in (tmp_path / "s").glob("*.png"))
