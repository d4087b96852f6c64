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


def run(*args, timeout=60):
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
    r = run("run", scene, "--quiet", "--no-plots", "--out", str(tmp_path / "o"), "--set", override, timeout=60)
    assert r.returncode == 2, r.stderr
    assert needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_run_checks_the_output_path_before_simulating(tmp_path):
    f = tmp_path / "file"
    f.write_text("")
    for out in (f, f / "sub", "/proc/forbidden/out"):
        r = run("run", "default", "--quiet", "--no-plots", "--out", str(out), "--set", "t_end_s=1000", timeout=30)
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
    o, e = p.communicate(timeout=60)
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
