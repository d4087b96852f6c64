"""`python -m host_emulator boards`: the image tier's boards as a laptop sees them, through the flash tool's own code:
the --ports-json listing, `ID?` on every port, the 1200-baud touch re-enumerating a board, --blank, SIGINT."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from metacell_tools.flash.boards import XIAO_PID_APP, XIAO_VID, port_lister, ports_from_json, xiao_ports
from metacell_tools.flash.bossac import touch_1200, wait_for_port
from metacell_tools.flash.identity import expected_fw_version, query_identity
from tests.conftest import ctrl_c_default

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[3]
WAIT_S = 1800.0  # generous: the boards run slower than real time, more so on a busy machine


def until(pred, timeout: float = WAIT_S, every: float = 0.05):
    """pred()'s first true value, waiting on the condition (never on a fixed time)."""
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        assert time.monotonic() < end, f"condition not met within {timeout} s"
        time.sleep(every)


def entries(listing: Path) -> list[dict]:
    try:
        return json.loads(listing.read_text())
    except (OSError, ValueError):
        return []


class Rig:
    """A `boards` process with its listing, stable names, stdout and stderr (files: nothing blocks on a pipe)."""

    def __init__(self, tmp: Path, *args: str, env: dict | None = None) -> None:
        self.listing = tmp / "ports.json"
        self.dev = tmp / "ports-dev"
        self.out, self.err = tmp / "out.txt", tmp / "err.txt"
        with open(self.out, "w") as out, open(self.err, "w") as err:
            self.p = subprocess.Popen(
                [sys.executable, "-m", "host_emulator", "boards", "--ports-json", str(self.listing), *args],
                cwd=ROOT,
                stdout=out,
                stderr=err,
                env=env,
                preexec_fn=ctrl_c_default,
            )
        self.t0 = time.monotonic()

    def wait_up(self, n: int) -> float:
        """Seconds until the process said every board is up; its listing then holds n ports."""
        until(lambda: "boards up" in self.out.read_text() or self.p.poll() is not None)
        assert self.p.poll() is None, (self.out.read_text(), self.err.read_text())
        up = time.monotonic() - self.t0
        until(lambda: len(entries(self.listing)) == n)
        return up

    def stop(self, sig=signal.SIGINT) -> int:
        if self.p.poll() is None:
            self.p.send_signal(sig)
        try:
            return self.p.wait(timeout=300)
        except subprocess.TimeoutExpired:
            self.p.kill()
            raise


@pytest.fixture(scope="module")
def rig3(images, tmp_path_factory):
    """Three boards without the bootloader (MC_BOOTLOADER unset: the touch resets from outside; with the bootloader
    the touch reaches the firmware: test_rigday)."""
    env = {k: v for k, v in os.environ.items() if k != "MC_BOOTLOADER"}
    r = Rig(tmp_path_factory.mktemp("boards3"), "--count", "3", env=env)
    r.wait_up(3)
    yield r
    r.stop()


def flash_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "metacell_tools.flash", *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


def test_listing_is_what_the_flash_tool_reads(rig3, tmp_path):
    ports = xiao_ports(ports_from_json(rig3.listing))  # the flash tool's own reader
    assert len(ports) == 3
    for j, p in enumerate(ports, 1):
        assert (p.vid, p.pid, p.in_bootloader) == (XIAO_VID, XIAO_PID_APP, False)
        assert "ttyACM" in os.path.basename(p.device) and p.device == str(rig3.dev / f"ttyACM-mc{j:02d}")
        assert os.readlink(p.device).startswith("/dev/pts/") and p.description.endswith(f"(emulated cell {j})")
    assert len({p.serial_number for p in ports}) == 3
    assert [e["mode"] for e in entries(rig3.listing)] == ["application"] * 3
    r = flash_cli("inventory", "--ports-json", str(rig3.listing), "--inventory", str(tmp_path / "none.json"))
    assert r.returncode == 0 and "connected XIAO boards (3):" in r.stdout, r
    assert r.stdout.count("UNASSIGNED") == 3


def test_listing_takes_ids_and_strings_from_the_boards_descriptors(rig3):
    """The listing's VID:PID, serial number, manufacturer and product are what each board's own descriptors said
    to the Linux profile of the tier's USB host: Seeed's core, its serial string made of the chip's serial number
    words, which the tier makes unique per board (csrc/sam_world.c)."""
    for k, e in enumerate(entries(rig3.listing)):
        words = (0x4D43584F, 0x49414F00 + k, 0x53414D44, 0x3231AA00 + k)
        assert e["serial_number"] == "".join(f"{w:08X}" for w in words)
        assert (e["vid"], e["pid"], e["manufacturer"], e["product"]) == (
            XIAO_VID,
            XIAO_PID_APP,
            "Seeed",
            "Seeeduino XIAO",
        )
        assert e["hwid"].startswith(f"USB VID:PID=2886:802F SER={e['serial_number']} ")


def test_identify_and_plan_through_the_flash_tool(rig3, tmp_path):
    listing, inv = str(rig3.listing), str(tmp_path / "inventory.json")
    r = flash_cli("identify", "--ports-json", listing, "--inventory", str(tmp_path / "none.json"))
    assert r.returncode == 0, r
    fw = expected_fw_version()
    for j in (1, 2, 3):
        assert f"ttyACM-mc{j:02d} " in r.stdout and f": cell {j} addr=0x{0x0F + j:02x} fw={fw}" in r.stdout, r.stdout
    # the boards recorded in an inventory as the tool's users do, then identified against it and planned
    for e in entries(rig3.listing):
        j = int(e["device"][-2:])
        a = flash_cli(
            "inventory", "--ports-json", listing, "--inventory", inv, "--assign", str(j), "--serial", e["serial_number"]
        )
        assert a.returncode == 0, a
    r = flash_cli("identify", "--ports-json", listing, "--inventory", inv)
    assert r.returncode == 0 and "MISMATCH" not in r.stdout, r
    r = flash_cli("plan", "--ports-json", listing, "--inventory", inv)
    if r.returncode == 0:  # this machine can build and upload: every board on its stable name
        for j in (1, 2, 3):
            assert f"on {rig3.dev / f'ttyACM-mc{j:02d}'}" in r.stdout, r.stdout
    else:  # it cannot: one line says what is missing, before any board is touched
        assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, r


def test_touch_re_enumerates_the_board_in_application_mode(rig3):
    lister = port_lister(rig3.listing)
    board = next(e for e in entries(rig3.listing) if e["device"].endswith("ttyACM-mc02"))
    serial, link = board["serial_number"], board["device"]
    touch_1200(link)  # the flash tool's own touch
    until(lambda: all(e["serial_number"] != serial for e in entries(rig3.listing)))  # the device left
    assert not os.path.lexists(link)
    back = wait_for_port(serial, lister, WAIT_S, bootloader=False)  # without the bootloader: the application
    assert back is not None and back.device == link and back.pid == XIAO_PID_APP
    again = next(e for e in entries(rig3.listing) if e["serial_number"] == serial)
    assert again["enumeration"] == board["enumeration"] + 1 and again["mode"] == "application"
    assert os.readlink(link) == again["pty"]
    q = query_identity(link, timeout=WAIT_S)
    assert q.identity is not None and (q.identity.cell, q.identity.addr) == (2, 0x11)
    notes = [ln for ln in rig3.err.read_text().splitlines() if "touch" in ln]
    assert len(notes) == 1 and "MC_BOOTLOADER" in notes[0] and "restarts directly" in notes[0], notes
    # the other boards were not touched
    assert [e["enumeration"] for e in entries(rig3.listing)] == [1, 2, 1]


def test_sigint_removes_ptys_and_listing(rig3):
    links = [e["device"] for e in entries(rig3.listing)]
    assert rig3.stop(signal.SIGINT) == 0, rig3.err.read_text()
    assert not rig3.listing.exists() and not any(os.path.lexists(x) for x in links)
    assert not rig3.dev.exists()  # made by the process, removed with it
    assert "ports and listing removed" in rig3.out.read_text()


@pytest.mark.parametrize("bootloader", [None, "file"])
def test_blank_needs_the_bootloader(tmp_path, bootloader):
    env = {k: v for k, v in os.environ.items() if k != "MC_BOOTLOADER"}
    if bootloader:
        (tmp_path / "bootloader.bin").write_bytes(b"\0" * 8192)
        env["MC_BOOTLOADER"] = str(tmp_path / "bootloader.bin")
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "boards", "--blank", "--ports-json", str(tmp_path / "p.json")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert r.returncode == 2 and r.stdout == "" and len(r.stderr.splitlines()) == 1, r
    assert "--blank needs the XIAO's bootloader" in r.stderr
    assert ("not set" in r.stderr) if bootloader is None else ("is not the XIAO bootloader's" in r.stderr)
    assert not (tmp_path / "p.json").exists()


def test_seventeen_boards_identify(images, tmp_path):
    r = Rig(tmp_path)
    try:
        up = r.wait_up(17)
        t0 = time.monotonic()
        ident = flash_cli("identify", "--ports-json", str(r.listing), "--inventory", str(tmp_path / "none.json"))
        took = time.monotonic() - t0
        assert ident.returncode == 0, ident
        lines = ident.stdout.splitlines()
        assert len(lines) == 17 and lines[-1].endswith(f"primary fw={expected_fw_version()}"), lines
        for j in range(1, 17):
            assert f": cell {j} addr=0x{0x0F + j:02x} " in lines[j - 1], lines
        print(f"17 boards up in {up:.1f} s; identify of all 17 in {took:.2f} s")
    finally:
        assert r.stop() == 0, r.err.read_text()
    assert not r.listing.exists()


def test_reset_from_outside_keeps_the_schedule(images):
    """World.reset (the touch's reset) on parked and running boards, the primary polling 16 cells: each board resets
    (cause SYST) and the boards never wait for each other. A reset at the world's time itself lands in the past of
    a parked board (it resumes before its next event): this seed stopped the world with "the boards wait for each
    other" at the 15th reset; it lands after the world's time, as a USB host action does."""
    import random

    from host_emulator.image.world import World
    from host_emulator.params import Params

    w = World(Params(cells=16), images)
    for b in w.boards:
        w.usb_attach(b.index)
    w.run_to(2.3)
    assert all(w.usb_info(b.index).configured for b in w.boards)
    rnd = random.Random(1)
    for _ in range(60):
        b = rnd.randrange(17)
        before = int(w.info(b).resets)
        w.reset(b)
        w.run_to(w.t + rnd.choice([0.0001, 0.0005, 0.001, 0.002, 0.003]))
        assert int(w.info(b).resets) == before + 1 and int(w.info(b).reset_cause) == 0x40  # PM.RCAUSE.SYST only
    w.run_to(w.t + 2.3)
    assert all(w.usb_info(b.index).configured for b in w.boards)  # every board enumerated again


def test_exit_with_parent_stops_the_boards_when_their_parent_is_killed(images, tmp_path):
    """`boards --exit-with-parent` (what `flash --emulated` starts) stops by itself, ptys and listing removed, when
    the process that started it is killed outright (as a test's timeout kills the flash tool): nothing is left
    running. Without the flag the boards run on (checked first, then stopped)."""
    env = {k: v for k, v in os.environ.items() if k != "MC_BOOTLOADER"}
    starter = (
        "import subprocess, sys, time\n"
        "p = subprocess.Popen([sys.executable, '-m', 'host_emulator', 'boards', '--count', '1', '--ports-json',"
        " sys.argv[1], *sys.argv[2:]], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)\n"
        "print(p.pid, flush=True)\n"
        "time.sleep(3600)\n"
    )
    for flag in ([], ["--exit-with-parent"]):
        listing = tmp_path / f"ports{len(flag)}.json"
        parent = subprocess.Popen(
            [sys.executable, "-c", starter, str(listing), *flag], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True
        )
        child = int(parent.stdout.readline())
        until(lambda listing=listing: len(entries(listing)) == 1)
        parent.kill()
        parent.wait()

        def alive(pid: int = child) -> bool:
            try:
                return "zombie" not in Path(f"/proc/{pid}/status").read_text()
            except OSError:
                return False

        if not flag:
            time.sleep(2.0)  # (an upper bound on nothing: the boards must simply still be there)
            assert alive() and len(entries(listing)) == 1
            os.kill(child, signal.SIGTERM)
        until(lambda: not alive())
        assert not listing.exists()
