"""`python -m host_emulator`: scenes listing, run writes a complete summary.json (never NaN), NPZ and plots; errors exit
non-zero."""

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from host_emulator.cli import main

ROOT = Path(__file__).resolve().parents[2]
KEYS = (
    "scene",
    "model",
    "t_end_s",
    "wall_s",
    "realtime_factor",
    "steady",
    "pattern_period_cells",
    "oscillation_period_s",
    "final_alpha_rad",
    "final_beta_rad",
)


def _no_nan(v):
    if isinstance(v, dict):
        return all(_no_nan(x) for x in v.values())
    if isinstance(v, list):
        return all(_no_nan(x) for x in v)
    return not (isinstance(v, float) and not math.isfinite(v))


def test_run_writes_summary_npz_and_plots(tmp_path, capsys):
    out = tmp_path / "d"
    rc = main(["run", "default", "--set", "t_end_s=3", "--out", str(out), "--quiet"])
    assert rc == 0
    text = (out / "summary.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    s = json.loads(text)
    for k in KEYS:
        assert k in s
    assert s["scene"] == "default" and s["model"] == "hil" and s["t_end_s"] == 3.0
    assert len(s["final_alpha_rad"]) == 16 and _no_nan(s)
    assert s["dispersion"]["regime"] == "stationary_pattern" and s["source"] == "emulator:hil"
    assert s["dispersion"]["theory"].startswith("hil: lattice with inertia + the motors' back-EMF damping")
    z = np.load(out / "trajectories.npz")
    assert z["alpha"].shape == (301, 16) and np.allclose(z["alpha"][-1], s["final_alpha_rad"])
    for f in ("spacetime.png", "final_pattern.png", "dispersion.png"):
        assert (out / f).stat().st_size > 1000
    printed = capsys.readouterr().out
    assert "summary.json" in printed and "spacetime.png" in printed


def test_unstable_run_exits_nonzero_without_summary(tmp_path, capsys):
    out = tmp_path / "u"
    rc = main(
        [
            "run",
            "exp3_single_sigma9",
            "--set",
            "params.sigma=0.112",
            "--set",
            "params.actuator_limit=false",
            "--set",
            "t_end_s=3",
            "--out",
            str(out),
            "--quiet",
            "--no-plots",
        ]
    )
    assert rc == 3
    assert re.search("band stretched|diverged", capsys.readouterr().err)
    assert not (out / "summary.json").exists()


def test_bad_scene_key_exits_2(capsys):
    assert main(["run", "default", "--set", "params.nope=1", "--quiet"]) == 2
    assert "params.nope" in capsys.readouterr().err


def test_module_entry_lists_scenes():
    r = subprocess.run([sys.executable, "-m", "host_emulator", "scenes"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0 and "default" in r.stdout and "exp5_rest" in r.stdout
