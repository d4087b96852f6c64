"""The rig day, emulated: `python -m metacell_tools.flash flash --emulated` flashes 17 blank emulated XIAOs with the
real bossac through their bootloader, and every board comes back running the image its plan wanted; the flash read
back holds the bootloader at 0x0000-0x1FFF and the image's .bin at 0x2000. Then the planted faults, each caught with
a clear message: another cell's image, an upload at offset 0, a board unplugged mid-upload, a bootloader port that
never appears. Needs MC_PIO_TREE (the images), MC_BOOTLOADER and bossac; skipped in one line otherwise."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from metacell_tools.flash.emulated import write_inventory

from .conftest import images_or_skip

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[3]
APP = 0x2000
TAGS = [f"mc{j:02d}" for j in range(1, 17)] + ["primary"]


@pytest.fixture(scope="module")
def prebuilt(tmp_path_factory) -> Path:
    """The images as the flash tool's --prebuilt takes them (DIR/cellNN/firmware.elf, DIR/primary/...)."""
    missing = [name for name, ok in (
        ("MC_PIO_TREE", os.environ.get("MC_PIO_TREE")),
        ("MC_BOOTLOADER", os.environ.get("MC_BOOTLOADER")),
        ("bossac", shutil.which("bossac")),
    ) if not ok]  # fmt: skip
    if missing:
        pytest.skip(f"rig day skipped: {', '.join(missing)} missing")
    images = images_or_skip()
    out = tmp_path_factory.mktemp("prebuilt")
    for j, elf in enumerate(images.cells, 1):
        (out / f"cell{j:02d}").mkdir()
        shutil.copy(elf, out / f"cell{j:02d}" / "firmware.elf")
    (out / "primary").mkdir()
    shutil.copy(images.primary, out / "primary" / "firmware.elf")
    return out


def flash(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    r = subprocess.run(
        [sys.executable, "-m", "metacell_tools.flash", "flash", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    print(r.stdout[-6000:], r.stderr[-3000:])
    return r


def bin_of(prebuilt: Path, tag: str) -> bytes:
    name = "primary" if tag == "primary" else f"cell{tag[2:]}"
    return (prebuilt / name / "firmware.bin").read_bytes()


def listed(listing: Path) -> int:
    try:
        return len(json.loads(listing.read_text()))
    except (OSError, ValueError):
        return 0


def test_seventeen_blank_boards_flashed_and_verified(prebuilt, tmp_path):
    control = tmp_path / "control"
    control.mkdir()
    t0 = time.monotonic()
    r = flash("--emulated", "--prebuilt", str(prebuilt), "--keep-going", "--log-dir", str(tmp_path / "logs"),
              "--emulated-control", str(control))  # fmt: skip
    took = time.monotonic() - t0
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr
    assert "17 of 17 board(s) flashed and verified" in r.stdout
    for j in range(1, 17):
        assert f"OK: ok: cell {j} addr=0x{0x0F + j:02x} fw=" in r.stdout
    assert "primary: OK: ok: primary fw=" in r.stdout
    boot = Path(os.environ["MC_BOOTLOADER"]).read_bytes()
    for tag in TAGS:
        flash_ = (control / f"flash-{tag}.bin").read_bytes()
        image = bin_of(prebuilt, tag)
        assert flash_[:APP] == boot, f"{tag}: the bootloader is not intact"
        assert flash_[APP : APP + len(image)] == image, f"{tag}: flash at 0x2000 is not its image's .bin"
    print(f"17 boards flashed and verified in {took:.0f} s")


def test_faults_are_caught_and_the_rest_go_on(prebuilt, tmp_path):
    """cell 1 gets cell 3's image (identity mismatch), cell 2 is unplugged mid-upload, cell 3 is flashed."""
    planted = tmp_path / "planted"
    shutil.copytree(prebuilt, planted)
    shutil.copy(prebuilt / "cell03" / "firmware.elf", planted / "cell01" / "firmware.elf")
    (planted / "cell01" / "firmware.bin").unlink(missing_ok=True)
    control = tmp_path / "control"
    control.mkdir()
    (control / "unplug-mc02-at-8192").touch()
    r = flash("--emulated", "--emulated-count", "3", "--prebuilt", str(planted), "--keep-going",
              "--log-dir", str(tmp_path / "logs"), "--emulated-control", str(control))  # fmt: skip
    assert r.returncode == 1
    assert "identity mismatch: expected cell 1 addr=0x10" in r.stdout and "board says cell 3 addr=0x12" in r.stdout
    assert "1 of 3 board(s) flashed and verified; FAILED: cell 1 (0x10), cell 2 (0x11)" in r.stdout
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("      cell 2 (0x11): FAILED"))
    assert "upload failed" in line and "left the USB bus during bossac" in line and "unplugged?" in line


def test_a_failure_stops_the_others_unless_asked(prebuilt, tmp_path):
    planted = tmp_path / "planted"
    shutil.copytree(prebuilt, planted)
    shutil.copy(prebuilt / "cell02" / "firmware.elf", planted / "cell01" / "firmware.elf")
    (planted / "cell01" / "firmware.bin").unlink(missing_ok=True)
    r = flash("--emulated", "--emulated-count", "2", "--jobs", "1", "--prebuilt", str(planted),
              "--log-dir", str(tmp_path / "logs"))  # fmt: skip
    assert r.returncode == 1
    assert "identity mismatch" in r.stdout
    assert "NOT TRIED (stopped at the first failure; --keep-going goes on): cell 2 (0x11)" in r.stdout


def test_an_upload_at_offset_0_is_refused_or_never_returns(prebuilt, tmp_path):
    r = flash("--emulated", "--emulated-count", "1", "--prebuilt", str(prebuilt), "--offset", "0")
    assert r.returncode == 2 and "would overwrite the XIAO's bootloader" in r.stderr
    r = flash("--emulated", "--emulated-count", "1", "--prebuilt", str(prebuilt), "--offset", "0",
              "--overwrite-bootloader", "--reappear-timeout", "20", "--log-dir", str(tmp_path / "logs"))  # fmt: skip
    assert r.returncode == 1
    # the bootloader erases itself under bossac (BOOTPROT protects nothing) or the board never restarts
    assert ("did not come back" in r.stdout or "upload failed" in r.stdout) and "overwrote the bootloader" in r.stdout


def test_a_bootloader_port_that_never_appears(prebuilt, tmp_path):
    """Two boards running their applications: cell 1 ignores the 1200-baud touch (flash says so and how to get it
    into its bootloader by hand), cell 2 takes it (Seeed's core resets into the bootloader) and is flashed."""
    listing, control = tmp_path / "ports.json", tmp_path / "control"
    control.mkdir()
    (control / "deaf-mc01").touch()
    with open(tmp_path / "boards.log", "w") as log:
        child = subprocess.Popen(
            [sys.executable, "-m", "host_emulator", "boards", "--count", "2", "--ports-json", str(listing),
             "--control", str(control)],
            cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip
    try:
        end = time.monotonic() + 300
        while listed(listing) < 2 or (control / "deaf-mc01").exists():
            assert child.poll() is None and time.monotonic() < end, (tmp_path / "boards.log").read_text()
            time.sleep(0.2)
        inventory = tmp_path / "boards.json"
        write_inventory(listing, inventory)
        r = flash("--ports-json", str(listing), "--inventory", str(inventory), "--prebuilt", str(prebuilt),
                  "--bootloader-timeout", "5", "--keep-going", "--log-dir", str(tmp_path / "logs"))  # fmt: skip
    finally:
        child.terminate()
        child.wait(60)
    assert r.returncode == 1
    assert "no bootloader port: cell 1 (0x10)" in r.stdout and "short its two RST pads twice" in r.stdout
    assert "OK: ok: cell 2 addr=0x11" in r.stdout
    assert "1 of 2 board(s) flashed and verified; FAILED: cell 1 (0x10)" in r.stdout
