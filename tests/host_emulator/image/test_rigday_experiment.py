"""The rig day's last step, emulated: 17 blank boards (`boards --blank --plant`) flashed by the flash tool, then the
experiment runner runs exp1_ccw_ccw on them through the real primary image; its capture (python-can's can.Logger
writes it) is read by he.load and lined up by compare with the hil model's run of the same scene. Same skip
conditions as test_rigday (MC_PIO_TREE, MC_BOOTLOADER, bossac)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time

import numpy as np
import pytest

import host_emulator as he
from metacell_tools.experiment.compare import compare
from metacell_tools.flash.emulated import write_inventory
from tests.conftest import ctrl_c_default

from . import test_rigday as rigday

pytestmark = pytest.mark.slow
ROOT = rigday.ROOT
prebuilt = rigday.prebuilt  # the same fixture (its skip conditions included)
SCENE, T_END = "exp1_ccw_ccw", 3.0
PUSHED = (6, 10)  # the scene's CCW pushes on alpha
WAIT_S = 900  # generous: 17 boards and the plant on a loaded 2-core machine run well below real time


def wait_for(what: str, ok, child: subprocess.Popen, log, timeout: float = WAIT_S) -> None:
    end = time.monotonic() + timeout
    while not ok():
        assert child.poll() is None, f"boards stopped before {what}: {log.read_text()[-3000:]}"
        assert time.monotonic() < end, f"no {what} after {timeout:.0f} s: {log.read_text()[-3000:]}"
        time.sleep(0.2)


def test_an_experiment_on_the_flashed_boards_is_logged_loaded_and_compared(prebuilt, tmp_path):
    listing, log = tmp_path / "ports.json", tmp_path / "boards.log"
    t0 = time.monotonic()
    with open(log, "w") as f:
        child = subprocess.Popen(
            [sys.executable, "-m", "host_emulator", "boards", "--blank", "--plant", "--ports-json",
             str(listing)],
            cwd=ROOT, stdout=f, stderr=subprocess.STDOUT, preexec_fn=ctrl_c_default,
        )  # fmt: skip
    try:
        wait_for("17 boards listed", lambda: rigday.listed(listing) == 17, child, log)
        assert "plant started" not in log.read_text()  # blank boards: the plant waits for the applications
        inventory = tmp_path / "boards.json"
        write_inventory(listing, inventory)
        # bossac gives each SAM-BA answer 0.1-5 s of wall time: its clock is slowed to the emulated boards' pace
        how = ["--ports-json", str(listing), "--inventory", str(inventory), "--prebuilt", str(prebuilt)]
        r = rigday.flash(*how, "--keep-going", "--jobs", "17", "--log-dir", str(tmp_path / "logs"),
                         "--bossac-clock-rate", "0.05")  # fmt: skip
        assert r.returncode == 0 and "17 of 17 board(s) flashed and verified" in r.stdout, r.stdout[-3000:]
        t_flashed = time.monotonic()
        wait_for("plant started", lambda: "plant started" in log.read_text(), child, log)
        primary = next(p["device"] for p in json.loads(listing.read_text()) if p["device"].endswith("ttyACM-primary"))
        out = tmp_path / "rig"
        # the runner is the port's one reader: its own can.Logger writes the capture (rig.asc)
        run = subprocess.run(
            [sys.executable, "-m", "metacell_tools.experiment", "run", SCENE, "-c", f"{primary}@115200",
             "--set", f"t_end_s={T_END}", "--no-early-stop", "--timeout", "20", "--silence", "30",
             "--rest-timeout", "300", "--out", str(out), "--no-plots"],
            cwd=ROOT, capture_output=True, text=True, timeout=WAIT_S,
        )  # fmt: skip
        t_run = time.monotonic()
        print(run.stdout[-4000:], run.stderr[-4000:])
        assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    finally:
        child.terminate()
        child.wait(120)
    # the runner labels a run on a pty "rehearsal:hil" and names its capture after that (rehearsal.asc): the boards'
    # ports are ptys; he.load is told what it is
    capture = out / "rehearsal.asc"
    ds = he.load(capture, source="rig")
    assert ds.attrs["source"] == "rig"
    alpha = ds["alpha"].values  # (time, cell)
    samples = np.isfinite(alpha).sum(axis=0)
    assert alpha.shape[1] == 16 and (samples >= 20).all(), samples  # every cell sampled all along
    for j in PUSHED:
        assert np.nanmax(np.abs(alpha[:, j - 1])) > 0.3, (j, alpha[:, j - 1])  # the pushed cells moved

    emu = tmp_path / "hil"
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "run", SCENE, "--set", f"t_end_s={T_END}",
         "--set", "model_options.perturb_via=firmware", "--out", str(emu), "--quiet", "--no-plots"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    # the capture's last samples come after the drive went off (the cells relax towards rest): the same pattern as
    # hil's, every clearly turned cell on the same side, smaller; measured rms 0.21 rad
    table, png = compare(capture, emu, tmp_path / "compare.png", ("rig", None))
    print(table)
    assert "A = rig" in table and "B = emulator:hil" in table and "over 16 cell(s)" in table
    assert png.stat().st_size > 5000
    hil = np.array(json.loads((emu / "summary.json").read_text())["final_alpha_rad"])
    last = np.array([alpha[np.flatnonzero(np.isfinite(alpha[:, j]))[-1], j] for j in range(16)])
    clear = np.abs(hil) > 0.2
    assert clear.sum() >= 12 and np.all(np.sign(last[clear]) == np.sign(hil[clear])), (last, hil)
    periods = [float(x) for x in re.findall(r"pattern period: A ([0-9.]+) cells, B ([0-9.]+) cells", table)[0]]
    assert abs(periods[0] - periods[1]) < 0.25 * periods[1], table
    # the run's own final profile (its summary, taken before the drive went off) lines up with hil's closely;
    # measured rms 0.06 rad (a different pattern is 0.5 rad or more)
    table, _ = compare(out, emu, tmp_path / "compare-run.png", (None, None))
    print(table)
    rms = float(table.split("rms difference: alpha ")[1].split(" rad")[0])
    print(f"flash {t_flashed - t0:.0f} s, experiment {t_run - t_flashed:.0f} s; rms {rms:.3f} rad")
    assert rms < 0.15, table
