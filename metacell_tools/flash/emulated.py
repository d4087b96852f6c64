"""`flash --emulated`: the rig day as a dry run: 17 blank emulated boards (the host emulator's `boards --blank`, a
child process), flashed through their listing with the real bossac and verified as real ones are.

The flash tool does not import the emulator (lint-imports): it starts `python -m host_emulator boards --blank` from
the project's root with a listing in a temporary directory, waits until every board is listed in bootloader mode (new
XIAOs hold only the bootloader), writes an inventory that gives each emulated place its cell (the listing's stable
names ttyACM-mc01..16, ttyACM-primary), runs the normal plan, and stops the child (SIGTERM: it removes its ports).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

from . import inventory as inv
from .boards import ports_from_json, xiao_ports

ENV_BOOTLOADER = "MC_BOOTLOADER"  # the host emulator's: the XIAO bootloader's .bin its blank boards run
N_BOARDS = 17
LISTING_TIMEOUT_S = 600.0  # the child's start (images, the bootloader's cycle tables) and 17 enumerations
STOP_TIMEOUT_S = 20.0
# timeouts on wall time for boards that run at 0.1-0.3x real time with 17 of them on a loaded machine
BOOTLOADER_TIMEOUT_S = 120.0  # (defaults: given on the command line, they win)
REAPPEAR_TIMEOUT_S = 180.0
IDENTITY_TIMEOUT_S = 60.0
# bossac's waits for an answer are fixed in wall time (0.1 s for its buffer command, 1 s, 5 s for a flash write);
# 17 boards in one emulation on a loaded machine run at 0.1-0.3x real time, and a client that the emulation cannot
# keep up with misses them (bossac then stops mid-upload and the bootloader is left inside a data transfer). So bossac
# runs under libfaketime (Debian's libfaketime) with its clock slowed to this rate of real time: its waits are 1/rate
# times longer. What it prints as durations is on that clock. 1 runs it as it is.
BOSSAC_CLOCK_RATE = 0.05
LIBFAKETIME = "libfaketime.so.1"
TOGETHER_S = 120.0  # the parallel uploads wait this long at most for each other (runner.Gate)


class EmulationError(RuntimeError):
    """The emulated boards could not be brought up; the message is one line."""


def find_libfaketime() -> str | None:
    """libfaketime's library (Debian's libfaketime package: /usr/lib/<multiarch>/faketime/libfaketime.so.1)."""
    found = sorted(Path("/usr").glob(f"lib*/**/faketime/{LIBFAKETIME}"))
    return str(found[0]) if found else None


def bossac_env(rate: float) -> dict[str, str]:
    """The environment that runs bossac on a clock at this rate of real time (libfaketime preloaded; nothing at rate
    1). bossac is preloaded directly, not started by the faketime wrapper, which forks: a bossac stopped by the
    flash tool (an unplugged board) must be the process it kills."""
    if rate == 1:
        return {}
    lib = find_libfaketime()
    if lib is None:
        raise EmulationError(
            f"a bossac clock rate below 1 needs libfaketime (Debian's libfaketime: apt-get install libfaketime; "
            f"tools/setup.sh installs it) to run bossac at {rate:g} of real time, or --bossac-clock-rate 1"
        )
    preload = " ".join(filter(None, [lib, os.environ.get("LD_PRELOAD", "")]))
    return {"LD_PRELOAD": preload, "FAKETIME": f"+0 x{rate:g}"}


def preflight() -> str:
    """Empty string when the emulated boards can be brought up, else the one line naming what is missing."""
    p = os.environ.get(ENV_BOOTLOADER, "").strip()
    if not p:
        return f"--emulated needs {ENV_BOOTLOADER}: the path of the XIAO bootloader's .bin (the blank boards run it)"
    if not Path(p).is_file():
        return f"--emulated: {ENV_BOOTLOADER}={p}: no such file"
    return ""


def place_of(device: str) -> tuple[str, int | None] | None:
    """(role, cell) of an emulated board from its stable name (…/ttyACM-mc05 -> ("cell", 5)), None if not one."""
    tail = Path(device).name.rpartition("ttyACM-")[2]
    if tail == "primary":
        return "primary", None
    if tail.startswith("mc") and tail[2:].isdigit():
        return "cell", int(tail[2:])
    return None


def write_inventory(listing: Path, path: Path) -> list[inv.Board]:
    """The inventory of the emulated boards: each listed board's serial number as its place's cell or primary."""
    boards = []
    for p in xiao_ports(ports_from_json(listing)):
        place = place_of(p.device)
        if place is not None and p.serial_number:
            boards.append(inv.Board(p.serial_number, place[0], place[1]))
    boards = inv.validate(boards)
    inv.save(path, boards)
    return boards


@contextmanager
def emulated_boards(
    root: Path,
    count: int = N_BOARDS,
    *,
    control: Path | None = None,
    extra: tuple[str, ...] = (),
    timeout: float = LISTING_TIMEOUT_S,
    out: Callable[[str], None] = print,
):
    """Yield (listing, inventory) of `count` blank emulated boards, all listed in bootloader mode; the child is
    stopped on the way out. EmulationError (one line) when they do not come up."""
    with tempfile.TemporaryDirectory(prefix="mc-emulated-") as tmp:
        listing, inventory, log = Path(tmp) / "ports.json", Path(tmp) / "boards.json", Path(tmp) / "boards.log"
        argv = [sys.executable, "-m", "host_emulator", "boards", "--blank", "--count", str(count), "--exit-with-parent"]
        argv += ["--ports-json", str(listing), *extra]
        if control is not None:
            argv += ["--control", str(control)]
        t0 = time.monotonic()
        with log.open("w") as f:
            child = subprocess.Popen(argv, cwd=root, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            _wait_listed(child, listing, log, count, timeout)
            out(f"{count} blank emulated board(s) up in {time.monotonic() - t0:.0f} s (listing {listing})")
            write_inventory(listing, inventory)
            yield listing, inventory
        finally:
            rc = child.poll()
            if rc is not None:
                out(f"error: the emulated boards stopped early (exit {rc}): {_last_line(log)}")
            elif control is not None:
                _dump(control, child)
            _stop(child)
            out(f"emulated boards: {_last_line(log)} ({time.monotonic() - t0:.0f} s of wall time)")


def _last_line(log: Path) -> str:
    lines = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()] if log.exists() else []
    return lines[-1].strip() if lines else "no output"


def _wait_listed(child: subprocess.Popen, listing: Path, log: Path, count: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while True:
        rc = child.poll()
        if rc is not None:
            raise EmulationError(f"the emulated boards stopped (exit {rc}): {_last_line(log)}")
        try:
            ports = xiao_ports(ports_from_json(listing)) if listing.exists() else []
        except ValueError:  # (PortListError) a listing being replaced is read again
            ports = []
        if len(ports) == count and all(p.in_bootloader for p in ports):
            return
        if time.monotonic() > end:
            raise EmulationError(
                f"{len(ports)} of {count} emulated boards listed in bootloader mode after {timeout:.0f} s: "
                f"{_last_line(log)}"
            )
        time.sleep(0.5)


def _dump(control: Path, child: subprocess.Popen, timeout: float = 60.0) -> None:
    """Every board's flash into the control directory (flash-TAG.bin) before the boards stop: what a test reads."""
    (control / "done-dump").unlink(missing_ok=True)
    (control / "dump").touch()
    end = time.monotonic() + timeout
    while not (control / "done-dump").exists() and child.poll() is None and time.monotonic() < end:
        time.sleep(0.1)


def _stop(child: subprocess.Popen) -> None:
    if child.poll() is None:
        os.killpg(child.pid, signal.SIGTERM)
        try:
            child.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)
            child.wait()


def listing_json(listing: Path) -> list[dict]:
    return json.loads(listing.read_text())
