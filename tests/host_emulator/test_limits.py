"""Every CLI value is checked before any work: bounded time, one-line error, exit code 2 (bad input)
or 3 (run failed)."""

import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.limits import check_run
from host_emulator.scene import list_scenes, load_scene
from metacell_tools.rigtools import proto

ROOT = proto.ROOT


def run(*args, timeout=600):
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )
    return r


def test_every_shipped_scene_passes_the_checks():
    for name, _, _ in list_scenes():
        assert check_run(load_scene(name)) is None, name


@pytest.mark.parametrize(
    "scene,override,needle",
    [
        ("default", "model_options.dt=1e-12", "cell steps"),
        ("default", "model_options.dt_out=1e9", "dt_out"),
        ("default", "model_options.noise.encoder_jitter_counts=1e12", "encoder_jitter_counts"),
        ("default", "params.band_scale=1e12", "band_scale"),
        ("default", "params.sigma=1e9", "int32"),
        ("default", "t_end_s=1e9", "GiB"),
        ("continuum_single", "model_options.points_per_cell=100000", "points_per_cell"),
        ("continuum_single", "params.eta_scale=1e-9", "eta_scale"),
    ],
)
def test_run_refuses_unbounded_or_unrepresentable_values(scene, override, needle, tmp_path):
    r = run("run", scene, "--quiet", "--no-plots", "--out", str(tmp_path / "o"), "--set", override, timeout=600)
    assert r.returncode == 2, r.stderr
    assert needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_run_checks_the_output_path_before_simulating(tmp_path):
    f = tmp_path / "file"
    f.write_text("")
    for out in (f, f / "sub", "/proc/forbidden/out"):
        r = run("run", "default", "--quiet", "--no-plots", "--out", str(out), "--set", "t_end_s=1000", timeout=600)
        assert r.returncode == 2 and "--out" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_dispersion_into_a_closed_pipe_is_not_an_error():
    p = subprocess.Popen(
        f"{sys.executable} -m host_emulator dispersion --json | head -c 5",
        shell=True,
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    o, e = p.communicate(timeout=600)
    assert "Traceback" not in e and "BrokenPipe" not in e, e


@settings(max_examples=40, deadline=None)
@given(
    st.sampled_from(
        [
            "params.sigma",
            "params.k1",
            "params.band_scale",
            "params.eta_scale",
            "t_end_s",
            "model_options.dt",
            "model_options.dt_out",
            "model_options.noise.encoder_jitter_counts",
        ]
    ),
    st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e-300, 1e300])),
)
def test_check_run_never_raises_and_refuses_what_it_cannot_bound(key, value):
    """Any float for a checked key: the scene loader or check_run refuses it with a message, or it is in range."""
    from host_emulator.models import ConfigError

    try:
        sc = load_scene("default", [f"{key}={value!r}"])
    except (ConfigError, KeyError, ValueError):
        return
    msg = check_run(sc)
    assert msg is None or key.split(".")[-1] in msg or "GiB" in msg or "cell steps" in msg


# ---- one guard for every path to a run (issue: substeps, tiny inertia, huge sweeps) ---------------------------


@pytest.mark.parametrize(
    "sets,needle",
    [
        (["model_options.substeps=1000000"], "model_options.substeps = 1000000"),
        (["model=lattice", "params.I_a=1e-15"], "automatic plant step"),
        (["model=lattice", "accuracy=exact", "params.I_a=1e-15"], "stepper dop853"),  # adaptive: its stable limit
    ],
)
def test_run_refuses_a_resolved_step_count_it_cannot_finish(sets, needle, tmp_path):
    args = ["run", "default", "--quiet", "--no-plots", "--out", str(tmp_path / "o")]
    for s in sets:
        args += ["--set", s]
    r = run(*args, timeout=300)
    assert r.returncode == 2 and needle in r.stderr and "cell steps" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_an_adaptive_lattice_run_is_judged_by_its_stable_limit():
    """dop853 (accuracy exact on the lattice) has no fixed step: its cost is judged from the step it can hold (the
    smaller of model_options.dt and the stable limit), so an ordinary run passes and a tiny inertia does not."""
    from host_emulator.controller import build_solver
    from host_emulator.limits import cell_steps, check_solver

    sc = load_scene("exp3_single_sigma14", ["model=lattice", "accuracy=exact"])
    s = build_solver(sc)
    assert s.adaptive and s.plant_step_s() == pytest.approx(s.limit) and check_solver(sc, s) is None
    assert cell_steps(sc, s) == pytest.approx(sc.t_end_s / s.limit * sc.cells)
    capped = load_scene("exp3_single_sigma14", ["model=lattice", "accuracy=exact", "model_options.dt=1e-4"])
    assert build_solver(capped).plant_step_s() == pytest.approx(1e-4)  # a dt below the limit caps the step
    tiny = load_scene("exp3_single_sigma14", ["model=lattice", "accuracy=exact", "params.I_a=1e-15"])
    msg = check_solver(tiny, build_solver(tiny))
    assert msg is not None and "dop853" in msg and "cell steps" in msg


def test_the_api_refuses_the_same_run():
    import host_emulator as he
    from host_emulator.limits import RunTooLarge
    from host_emulator.models import ConfigError

    with pytest.raises(RunTooLarge, match="substeps") as e:
        he.run("default", {"model_options.substeps": 1_000_000})
    assert isinstance(e.value, ConfigError)


def test_serve_refuses_a_step_it_cannot_pace():
    r = run("serve", "default", "--duration", "60", "--set", "model_options.substeps=1000", timeout=300)
    assert r.returncode == 2 and "real time" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.mark.parametrize(
    "grid,needle",
    [
        (["--grid", "params.sigma=0.04:0.12:100000000"], "exceeds"),
        (["--grid", "params.sigma=0.04:0.12:10000", "--grid", "params.k1=0.06,0.07", "--seeds", "100"], "points"),
        (["--grid", "params.sigma=0.04:0.12:1000", "--seeds", "1000"], "cell steps in all"),
        (["--grid", "model_options.substeps=1,1000000"], "model_options.substeps = 1000000"),
    ],
)
def test_sweep_refuses_what_it_cannot_finish_before_any_cluster(grid, needle, tmp_path):
    r = run("sweep", "default", "--quiet", "--out", str(tmp_path / "s"), *grid, timeout=300)
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "s" / "points.jsonl").exists()


def test_sweep_unreachable_scheduler_is_one_line_exit_3(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens at
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = run(
        "sweep", "default", "--quiet", "--grid", "params.sigma=0.05", "--out", str(tmp_path / "s"),
        "--scheduler", f"tcp://127.0.0.1:{port}", timeout=300,
    )  # fmt: skip
    assert r.returncode == 3 and "cannot connect" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_sweep_interrupted_is_one_line_exit_3_and_resumable(tmp_path):
    import signal
    import time

    from tests.conftest import ctrl_c_default

    out = tmp_path / "s"
    p = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "sweep", "default", "--grid", "params.sigma=0.04:0.12:400",
         "--workers", "1", "--chunk", "4", "--out", str(out)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_default,
    )  # fmt: skip
    pf = out / "points.jsonl"
    deadline = time.monotonic() + 300  # event-driven: the first finished chunk, however slow the machine
    while not (pf.exists() and pf.stat().st_size) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert p.poll() is None, "the sweep ended before it could be interrupted"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 3 and "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("sweep: interrupted"), err
    done = len(pf.read_text().splitlines())
    r = run("sweep", "default", "--quiet", "--grid", "params.sigma=0.04:0.12:400", "--workers", "1",
            "--out", str(out), timeout=900)  # fmt: skip
    assert r.returncode == 0 and 0 < done < 400 and len(pf.read_text().splitlines()) == 400, r.stderr


def test_pathological_scene_files_are_one_line(tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    junk = tmp_path / "junk.toml"
    junk.write_bytes(bytes(range(256)) * 4)
    for f in (deep, junk):
        r = run("run", str(f), "--quiet", "--out", str(tmp_path / "o"), timeout=300)
        assert r.returncode == 2 and str(f) in r.stderr and "Traceback" not in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1


def test_an_integer_too_big_for_the_firmware_names_its_key(tmp_path):
    r = run("run", "default", "--quiet", "--no-plots", "--out", str(tmp_path / "o"),
            "--set", "params.pwm_top=99999999999999999999999", timeout=300)  # fmt: skip
    assert r.returncode == 2 and "params.pwm_top" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.mark.parametrize("kind", ["not-a-run", "empty", "cut", "junk"])
def test_compare_on_a_bad_npz_is_one_line(tmp_path, kind):
    """compare opens logger NPZs now (issue 21: he.load); an NPZ that is no run, empty (a full disk before the
    logger's atomic write), cut or not an NPZ at all is one line naming the file, exit 2."""
    import numpy as np

    npz = tmp_path / "run.npz"
    np.savez(npz, a=np.zeros(3))
    data = npz.read_bytes()
    if kind == "empty":
        npz.write_bytes(b"")
    elif kind == "cut":
        npz.write_bytes(data[: len(data) // 2])
    elif kind == "junk":
        npz.write_bytes(b"\x00junk" * 100)
    (tmp_path / "emu").mkdir()
    r = subprocess.run(
        [sys.executable, "-m", "metacell_tools.experiment", "compare", str(npz), str(tmp_path / "emu")],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    err = r.stderr.strip()
    assert r.returncode == 2 and str(npz) in err and "Traceback" not in err and len(err.splitlines()) == 1, err


def test_an_unforeseen_error_is_one_line_exit_3(monkeypatch, capsys):
    from numpy.linalg import LinAlgError

    import host_emulator.cli as cli

    def boom(*a, **k):
        raise LinAlgError("Singular matrix")

    monkeypatch.setattr(cli, "cmd_scenes", boom)
    monkeypatch.delenv("MC_DEBUG", raising=False)
    assert cli.main(["scenes"]) == 3
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "numerical failure: LinAlgError: Singular matrix" in err
