"""Nothing already captured is overwritten: the logger refuses an --out that holds a capture (a killed run's, a
repaired one's), one line, exit 2, every file unchanged; --overwrite replaces it; a run that recorded nothing is
no capture."""

import subprocess
import sys

import pytest

from metacell_tools.rigtools import logger as L
from metacell_tools.rigtools import proto

ROOT = proto.ROOT
ROWS = "0,1,1,0.000128,1000.000000,10,-5,0\n0,1,2,0.000640,1000.000500,12,-6,0\n0,2,1,0.010128,1000.010000,11,-5,0\n"


def run_logger(*args):
    return subprocess.run(
        [sys.executable, "-m", "metacell_tools.rigtools.logger", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _killed_run(prefix):
    """What a SIGKILLed `--formats asc,blf` run leaves: the streamed CSV, the ASC, a cut BLF, no NPZ."""
    prefix.with_suffix(".csv").write_text(L.CSV_HEADER + ROWS)
    prefix.with_suffix(".asc").write_text("date Thu Nov 26 17:00:00.000 2026\nbase hex  timestamps absolute\n")
    prefix.with_suffix(".blf").write_bytes(b"LOGG" + bytes(100))
    return {p: p.read_bytes() for p in prefix.parent.iterdir()}


@pytest.mark.parametrize("repaired", [False, True], ids=["killed", "repaired"])
def test_an_out_that_holds_a_capture_is_refused_and_left_alone(tmp_path, repaired):
    prefix = tmp_path / "run"
    before = _killed_run(prefix)
    if repaired:
        r = run_logger("--repair", str(prefix))
        assert r.returncode == 0, r.stderr
        before = {p: p.read_bytes() for p in tmp_path.iterdir()}
        assert prefix.with_suffix(".npz") in before
    r = run_logger("-c", "/dev/nonexistent-port@115200", "-o", str(prefix), "--formats", "asc,blf", "--duration", "1")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "holds 3 samples" in lines[0] and "--overwrite" in lines[0], r.stderr
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == before  # nothing changed, nothing added


def test_overwrite_replaces_the_capture(tmp_path):
    prefix = tmp_path / "run"
    _killed_run(prefix)
    r = run_logger(
        "-c", "/dev/nonexistent-port@115200", "-o", str(prefix), "--formats", "asc", "--duration", "1", "--overwrite"
    )
    assert r.returncode == 3 and "removed the capture" in r.stderr, r.stderr  # past the check: the port fails
    assert not prefix.with_suffix(".blf").exists()  # the old run's files are gone, not mixed with the new run's
    assert prefix.with_suffix(".csv").read_text() == L.CSV_HEADER


def test_a_run_that_recorded_nothing_is_no_capture(tmp_path):
    prefix = tmp_path / "run"
    for _ in range(2):  # the second run finds the first's empty files: not refused
        r = run_logger("-c", "/dev/nonexistent-port@115200", "-o", str(prefix), "--duration", "1")
        assert r.returncode == 3 and "holds" not in r.stderr, r.stderr
    assert L.held_capture(prefix) is None
    assert L.held_capture(tmp_path / "other") is None
