"""Flashing tool, the bossac upload: the 1200-baud touch, the bootloader's port, bossac's command line and its errors,
stop at the first failure or --keep-going, with stand-in `pio` and `bossac` executables and a port listing they share
(and once over a pty, once with the real bossac against nothing)."""

from __future__ import annotations

import json
import os
import pty
import re
import select
import shutil
import subprocess
import sys
import termios
import threading
import time
from pathlib import Path

import pytest

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import emulated
from metacell_tools.flash import inventory as inv
from metacell_tools.flash import runner as rn
from metacell_tools.flash.boards import XIAO_PID_APP, XIAO_PID_BOOT, XIAO_VID, ports_from_json
from metacell_tools.flash.bossac import BossacUpload, touch_1200, uploader_error
from metacell_tools.flash.identity import Identity, QueryResult
from metacell_tools.flash.plan import make_plan, with_toolchain
from metacell_tools.flash.toolchain import find_toolchain
from tests.tools.flash_fakes import calls, fake_inventory, pio_tools, write_exe

BOSSAC_TAIL = ["--usb-port=1", "--info", "--offset=0x2000", "--erase", "--write", "--verify", "--reset"]


class StandInRig:
    """n boards in a port listing shared with the stand-in bossac (FAKE_PORTS). The touch puts a board in its
    bootloader under a new device name (a re-enumeration may give one); bossac flashes it and brings it back on its
    own name; ID? answers what was flashed (the stand-in build's flags)."""

    def __init__(self, tmp_path, bin_dir, monkeypatch, n=17, stuck=(), boot=()):
        self.listing, self.bin_dir = tmp_path / "ports.json", bin_dir
        monkeypatch.setenv("FAKE_PORTS", str(self.listing))
        self.stuck, self.touched = set(stuck), []
        serials = [f"SN{i:02d}" for i in range(n)]
        self.write(
            [
                {"device": f"/dev/ttyACM{i}", "vid": XIAO_VID, "pid": XIAO_PID_APP, "serial_number": sn}
                | ({"pid": XIAO_PID_BOOT, "device": f"/dev/ttyACM{100 + i}", "app_device": f"/dev/ttyACM{i}"}
                   if sn in boot else {})
                for i, sn in enumerate(serials)
            ]
        )  # fmt: skip

    def read(self) -> list[dict]:
        return json.loads(self.listing.read_text())

    def write(self, ports: list[dict]) -> None:
        tmp = self.listing.with_suffix(".tmp")
        tmp.write_text(json.dumps(ports))
        tmp.replace(self.listing)

    def list_ports(self):
        return ports_from_json(self.listing)

    def touch(self, device: str) -> None:
        self.touched.append(device)
        ports = self.read()
        p = next(p for p in ports if p["device"] == device)
        if p["serial_number"] not in self.stuck:
            n = int(device.removeprefix("/dev/ttyACM"))
            p.update(pid=XIAO_PID_BOOT, device=f"/dev/ttyACM{100 + n}", app_device=device)
            self.write(ports)

    def flashed(self) -> dict:
        f = self.bin_dir / "flashed.json"
        return json.loads(f.read_text()) if f.exists() else {}

    def query(self, device: str) -> QueryResult:
        serial = next(p["serial_number"] for p in self.read() if p["device"] == device)
        return QueryResult(identity_of(self.flashed()[serial]["content"]), [], [])


def identity_of(firmware: str) -> Identity:
    """What a board running the stand-in build's firmware.bin answers to ID?."""
    m = re.search(r"MC_CELL_INDEX=(\d+) -DMC_CELL_ADDR=0x([0-9a-f]+)", firmware)
    return Identity("cell", "1.0", int(m.group(1)), int(m.group(2), 16)) if m else Identity("primary", "1.0")


def bossac_plan(rig, proj, only=None, **tools_kw):
    proj.mkdir(exist_ok=True)
    plan = make_plan(fake_inventory(), rig.list_ports(), project=proj, only=only)
    return with_toolchain(plan, find_toolchain("pio", proj, **tools_kw), proj)


def flasher(rig, tmp_path, lines=None, **kw):
    t = [0.0]  # a clock that moves only when the tool waits
    opts = dict(sleep=lambda s: t.__setitem__(0, t[0] + s), clock=lambda: t[0], reappear_timeout=1.0)
    return rn.Flasher(
        rig.list_ports,
        expected_fw="1.0",
        query=rig.query,
        touch=rig.touch,
        log_dir=tmp_path / "logs",
        out=(lines if lines is not None else []).append,
        **{**opts, **kw},
    )


def test_bossac_command_line_and_the_real_bossac_takes_it(tmp_path):
    """The command bossac 1.9.1 needs (Seeed's `-U true` of bossac 1.7 is an error there); the real one, when
    installed, parses it and fails on a port with nothing behind it, saying so on stderr."""
    up = BossacUpload("bossac", tmp_path / "firmware.bin")
    assert up.argv("/dev/ttyACM7") == ("bossac", "--port=/dev/ttyACM7", *BOSSAC_TAIL, str(tmp_path / "firmware.bin"))
    assert BossacUpload("b", Path("f.bin"), 0x4000).argv("P")[4] == "--offset=0x4000"
    real = shutil.which("bossac")
    if real is None:
        pytest.skip("bossac (Debian's bossa-cli) is not installed")
    (tmp_path / "firmware.bin").write_bytes(b"\0" * 256)
    r = subprocess.run([real, *up.argv("/dev/null")[1:]], capture_output=True, text=True, timeout=60)
    assert (r.returncode, r.stdout, r.stderr) == (1, "", "No device found on /dev/null\n")
    seeed = [real, "--port=/dev/null", "-U", "true", "-i", "--offset=0x2000", "-e", "-w", "-v", up.argv("")[-1], "-R"]
    r = subprocess.run(seeed, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "extra arguments found" in r.stderr


def test_17_boards_through_the_touch_the_bootloader_port_and_bossac(tmp_path, monkeypatch):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch, boot={"SN02"})  # cell 3 arrives in its bootloader
    proj = tmp_path / "proj"
    outcomes = flasher(rig, tmp_path).flash(bossac_plan(rig, proj), stop_on_error=True)
    assert [o.status for o in outcomes] == [rn.OK] * 17, [o.detail for o in outcomes if not o.ok]
    assert rig.touched == [f"/dev/ttyACM{i}" for i in range(17) if i != 2]  # a board in its bootloader is not touched
    done = calls(bin_dir)
    assert len(done) == 34
    for i, (build, upload) in enumerate(zip(done[::2], done[1::2])):
        name, env = ("build-primary", "primary") if i == 16 else (f"build-cell{i + 1:02d}", "cell")
        assert build["argv"][1:] == ["run", "-d", str(proj), "-e", env]  # a build only: no `-t upload`
        assert build["PLATFORMIO_BUILD_DIR"] == str(proj / ".pio" / name)
        fw = proj / ".pio" / name / env / "firmware.bin"
        assert upload["argv"] == [str(bin_dir / "bossac"), f"--port=/dev/ttyACM{100 + i}", *BOSSAC_TAIL, str(fw)]
        assert rig.flashed()[f"SN{i:02d}"] == {"content": fw.read_text(), "offset": 0x2000}
    assert [p.device for p in rig.list_ports()] == [f"/dev/ttyACM{i}" for i in range(17)]  # all back, in app mode
    assert outcomes[4].detail == "cell 5 addr=0x14 fw=1.0 on /dev/ttyACM4"
    log = (tmp_path / "logs" / "cell05.log").read_text()
    assert log.startswith("$ PLATFORMIO_BUILD_DIR=") and "1200-baud touch of /dev/ttyACM4\n" in log
    fw = proj / ".pio" / "build-cell05" / "cell" / "firmware.bin"
    assert f"$ {BossacUpload(str(bin_dir / 'bossac'), fw).shell('/dev/ttyACM104')}\n" in log
    assert log.endswith("Verify successful\nDone in 0.1 seconds\n")  # bossac's output


def cli_flash(tmp_path, monkeypatch, rig, *args, **flasher_kw):
    """`python -m metacell_tools.flash flash ...` in this process, the stand-in rig behind the ports and ID?."""
    t = [0.0]
    monkeypatch.setattr(
        cli,
        "Flasher",
        lambda lister, **kw: rn.Flasher(
            lister,
            query=rig.query,
            touch=rig.touch,
            sleep=lambda s: t.__setitem__(0, t[0] + s),
            clock=lambda: t[0],
            **{**kw, "expected_fw": "1.0", **flasher_kw},
        ),
    )
    inv.save(tmp_path / "b.json", fake_inventory())
    base = ["flash", "--inventory", str(tmp_path / "b.json"), "--ports-json", str(rig.listing)]
    (tmp_path / "proj").mkdir(exist_ok=True)
    return cli.main(base + ["--log-dir", str(tmp_path / "logs"), "--project", str(tmp_path / "proj"), *args])


@pytest.mark.parametrize("keep_going", [False, True])
def test_stops_at_the_first_failure_unless_keep_going(tmp_path, monkeypatch, capsys, keep_going):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    monkeypatch.setenv("FAKE_BOSSAC_FAIL", "SN04")  # cell 5's upload fails
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(tmp_path, monkeypatch, rig, *(["--keep-going"] if keep_going else []))
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED
    why = (
        "upload failed: Done in 0.7 seconds | Write 50 bytes to flash (1 pages) | SAM-BA operation failed (bossac "
        "exited with 1 on /dev/ttyACM104, the board's bootloader port) (2 attempts)"
    )
    assert "cell 5 (0x14): bossac failed: " in out and "; retry 1 of 1 on /dev/ttyACM104" in out
    assert f"      FAILED: {why} (log {tmp_path / 'logs' / 'cell05.log'})" in out
    assert f"  cell 5 (0x14)      SN04                     FAILED    {why}\n" in out
    builds = [c for c in calls(bin_dir) if c["argv"][0].endswith("pio")]
    if keep_going:
        assert len(builds) == 17 and "16 of 17 board(s) flashed and verified; FAILED: cell 5 (0x14)\n" in out
    else:  # nothing after cell 5 was built or touched
        assert len(builds) == 5 and rig.touched == [f"/dev/ttyACM{i}" for i in range(5)]
        assert (
            "  cell 6 (0x15)      SN05                     NOT TRIED not run: stopped after an earlier failure" in out
        )
        assert "4 of 17 board(s) flashed and verified; FAILED: cell 5 (0x14); NOT TRIED (stopped at the first " in out


@pytest.mark.parametrize("retries", [None, 0, 2])
def test_a_failed_bossac_is_run_again_while_the_board_stays_in_its_bootloader(tmp_path, monkeypatch, capsys, retries):
    """cell 5's first upload fails (the board stays in its bootloader): the default --retries 1 runs bossac again on
    that port and the board is flashed, saying so; --retries 0 gives up at once; nothing else is run twice."""
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    monkeypatch.setenv("FAKE_BOSSAC_FAIL_ONCE", "SN04")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    more = [] if retries is None else ["--retries", str(retries)]
    rc = cli_flash(tmp_path, monkeypatch, rig, "--keep-going", *more)
    out = capsys.readouterr().out
    uploads = [c for c in calls(bin_dir) if Path(c["argv"][0]).name == "bossac"]
    ports = [c["argv"][1] for c in uploads]
    if retries == 0:
        assert rc == cli.EXIT_FAILED and len(uploads) == 17 and "retry" not in out
        assert "16 of 17 board(s) flashed and verified; FAILED: cell 5 (0x14)\n" in out
        return
    assert rc == cli.EXIT_OK, out
    assert len(uploads) == 18 and ports.count("--port=/dev/ttyACM104") == 2
    assert f"; retry 1 of {retries or 1} on /dev/ttyACM104" in out
    assert "OK: ok: cell 5 addr=0x14 fw=1.0 on /dev/ttyACM4 (after 1 bossac retry)" in out
    assert "17 of 17 board(s) flashed and verified" in out


@pytest.mark.parametrize("rate", [None, "1", "0.05"])
def test_bossac_runs_on_a_slowed_clock_when_asked(tmp_path, monkeypatch, capsys, rate):
    """--bossac-clock-rate R < 1 runs every bossac with libfaketime preloaded at R (its waits 1/R times longer), bossac
    itself the process the tool started; 1 and the default run it as it is."""
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    lib = tmp_path / "lib" / "libfaketime.so.1"  # (not loadable: ld.so says so on stderr and goes on)
    monkeypatch.setattr(emulated, "find_libfaketime", lambda: str(lib))
    monkeypatch.delenv("LD_PRELOAD", raising=False)
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(
        tmp_path, monkeypatch, rig, "--only", "2,7", *([] if rate is None else ["--bossac-clock-rate", rate])
    )
    assert rc == cli.EXIT_OK, capsys.readouterr().out
    bossacs = [c for c in calls(bin_dir) if Path(c["argv"][0]).name == "bossac"]
    assert len(bossacs) == 2
    if rate == "0.05":
        assert [c.get("clock") for c in bossacs] == [{"FAKETIME": "+0 x0.05", "LD_PRELOAD": str(lib)}] * 2
    else:
        assert [c.get("clock") for c in bossacs] == [None, None]


@pytest.mark.parametrize("rate, why", [("0", "must be 0.001..1, got 0"), ("2", "must be 0.001..1, got 2"),
                                       ("0.1", "needs libfaketime")])  # fmt: skip
def test_a_bossac_clock_that_cannot_be_is_refused_before_any_board_is_touched(tmp_path, monkeypatch, capsys, rate, why):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    monkeypatch.setattr(emulated, "find_libfaketime", lambda: None)
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(tmp_path, monkeypatch, rig, "--bossac-clock-rate", rate)
    err = capsys.readouterr().err
    assert rc != cli.EXIT_OK and why in err and len(err.strip().splitlines()) == 1, err
    assert rig.touched == [] and calls(bin_dir) == []


def test_libfaketime_slows_the_clock_bossac_waits_on():
    """The environment given to bossac does slow a select() wait as bossac's read of an answer is made (when
    Debian's faketime is installed): 0.1 s at rate 0.1 takes a second."""
    if emulated.find_libfaketime() is None:
        pytest.skip("libfaketime (Debian's faketime) is not installed")
    code = "import select, time; t = time.perf_counter(); select.select([], [], [], 0.1)"
    env = {**os.environ, **emulated.bossac_env(0.1)}
    t0 = time.monotonic()
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=60)
    assert time.monotonic() - t0 >= 0.9


def test_a_board_unplugged_while_bossac_writes_is_named_and_not_retried(tmp_path, monkeypatch, capsys):
    """bossac fails because the board left the bus (its port gone from the listing, not back within 5 s): the detail
    says so, whatever bossac printed, and bossac is not run again on a port that is not there."""
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    monkeypatch.setenv("FAKE_BOSSAC_UNPLUG", "SN04")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(tmp_path, monkeypatch, rig, "--keep-going")
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED and "retry" not in out
    line = next(ln for ln in out.splitlines() if ln.startswith("  cell 5 (0x14)"))
    gone = "upload failed: the board (serial SN04) left the USB bus during bossac and did not come back within 5 s: "
    assert gone + "unplugged? (bossac: " in line
    assert line.endswith("| Write 50 bytes to flash (1 pages) | SAM-BA operation failed)")
    assert [Path(c["argv"][0]).name for c in calls(bin_dir)].count("bossac") == 17


def test_retries_out_of_range_are_refused_before_any_board_is_touched(tmp_path, monkeypatch, capsys):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(tmp_path, monkeypatch, rig, "--retries", "-1")
    err = capsys.readouterr().err
    assert rc != cli.EXIT_OK and "--retries must be 0..10, got -1" in err
    assert rig.touched == [] and calls(bin_dir) == []


@pytest.mark.parametrize("what", ["build", "bossac", "no bin, no objcopy", "no bin, objcopy", "unplugged"])
def test_the_real_error_is_shown(tmp_path, monkeypatch, what):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    monkeypatch.setenv("FAKE_PIO_FAIL", "build-cell03" if what == "build" else "")
    monkeypatch.setenv("FAKE_BOSSAC_FAIL", "SN02" if what == "bossac" else "")
    monkeypatch.setenv("FAKE_PIO_NO_BIN", "build-cell03" if what.startswith("no bin") else "")
    if what == "no bin, objcopy":  # PlatformIO made no .bin: made from the ELF, as arm-none-eabi-objcopy would
        objcopy = "import shutil, sys\nassert sys.argv[1:3] == ['-O', 'binary']\nshutil.copy(*sys.argv[3:5])\n"
        write_exe(bin_dir / "arm-none-eabi-objcopy", objcopy)
    plan = bossac_plan(rig, tmp_path / "proj", only={3})
    if what == "unplugged":
        rig.write([p for p in rig.read() if p["serial_number"] != "SN02"])
    (o,) = flasher(rig, tmp_path).flash(plan)
    if what == "no bin, objcopy":
        assert o.ok and o.detail == "cell 3 addr=0x12 fw=1.0 on /dev/ttyACM2"
        return
    status, detail = {
        "build": (
            rn.BUILD_FAILED,
            "Processing cell (platform: atmelsam@8.3.0; board: seeed_xiao; framework: arduino) | Platform Manager: "
            "Installing atmelsam @ 8.3.0 | Error: HTTPClientError: (PlatformIO tried to download a package: offline, "
            "see docs/hardware.md#flashing-offline) (pio exited with 1)",
        ),
        "bossac": (
            rn.UPLOAD_FAILED,
            "Done in 0.7 seconds | Write 50 bytes to flash (1 pages) | SAM-BA operation failed (bossac exited with 1 "
            "on /dev/ttyACM102, the board's bootloader port)",
        ),
        "no bin, no objcopy": (rn.BUILD_FAILED, "the build left no firmware.bin, and arm-none-eabi-objcopy cannot"),
        "unplugged": (rn.UPLOAD_FAILED, "serial SN02 is no longer connected"),
    }[what]
    assert o.status == status and o.detail.startswith(detail), o.detail
    assert not rig.flashed()


def test_uploader_error_keeps_the_message_and_drops_platformios_framing():
    out = """Processing cell (platform: atmelsam@8.3.0; board: seeed_xiao; framework: arduino)
--------------------------------------------------------------------------------
Compiling .pio/build-cell01/cell/src/cell/main.c.o
src/cell/main.c:12:5: error: 'x' undeclared (first use in this function)
*** [.pio/build-cell01/cell/src/cell/main.c.o] Error 1
========================= [FAILED] Took 2.13 seconds =========================

Environment    Status    Duration
-------------  --------  ------------
cell           FAILED    00:00:02.134
==================== 1 failed, 0 succeeded in 00:00:02.134 ====================
"""
    assert uploader_error(out, lines=2) == (
        "Compiling .pio/build-cell01/cell/src/cell/main.c.o | src/cell/main.c:12:5: error: 'x' undeclared (first use "
        "in this function)"
    )
    assert uploader_error("\n\n") == "no output"
    assert uploader_error("bossac: extra arguments found\n").endswith("use Debian's bossa-cli 1.9)")


@pytest.mark.parametrize("timeout", [None, 3])
def test_a_bootloader_port_that_never_appears_names_the_board(tmp_path, monkeypatch, capsys, timeout):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch, stuck={"SN05"})  # cell 6 ignores the touch
    rc = cli_flash(tmp_path, monkeypatch, rig, *(["--bootloader-timeout", str(timeout)] if timeout else []))
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED
    want = (
        f"FAILED: no bootloader port: cell 6 (0x15) serial SN05: its bootloader's port did not appear within "
        f"{timeout or 10} s of the 1200-baud touch of /dev/ttyACM5; put it in its bootloader by hand (short its two "
        "RST pads twice, quickly) and flash it again, or allow longer with --bootloader-timeout"
    )
    assert want in out
    assert [c["argv"][1] for c in calls(bin_dir) if "bossac" in c["argv"][0]] == [
        f"--port=/dev/ttyACM{100 + i}" for i in range(5)
    ]  # no bossac for cell 6, nothing after it
    assert "5 of 17 board(s) flashed and verified; FAILED: cell 6 (0x15); NOT TRIED" in out


def test_real_bossac_against_nothing_shows_its_words(tmp_path, monkeypatch):
    """The real bossac given a 'bootloader port' with nothing behind it (/dev/null): its own message is the detail."""
    real = shutil.which("bossac")
    if real is None:
        pytest.skip("bossac (Debian's bossa-cli) is not installed")
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="none")
    (tmp_path / "core" / "platforms" / "atmelsam").mkdir(parents=True)
    rig = StandInRig(tmp_path, bin_dir, monkeypatch, n=1, boot={"SN00"})
    rig.write([p | {"device": "/dev/null"} for p in rig.read()])
    inv_one = fake_inventory(1)[:1]
    plan = with_toolchain(
        make_plan(inv_one, rig.list_ports(), project=tmp_path), find_toolchain("pio", tmp_path, bossac=real), tmp_path
    )
    (o,) = flasher(rig, tmp_path).flash(plan)
    assert o.status == rn.UPLOAD_FAILED
    assert o.detail == (
        "No device found on /dev/null (nothing answered bossac on that port: not this board's bootloader, or it left "
        "it) (bossac exited with 1 on /dev/null, the board's bootloader port) (2 attempts)"
    )


def test_forced_upload_at_0_is_reported_as_a_lost_bootloader(tmp_path, monkeypatch, capsys):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch)
    rc = cli_flash(tmp_path, monkeypatch, rig, "--only", "1", "--offset", "0", "--overwrite-bootloader")
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED and rig.flashed()["SN00"]["offset"] == 0
    assert (
        "FAILED: did not come back: no application port with serial SN00 within 20 s after upload; the upload at 0x0 "
        "overwrote the bootloader, so the board can neither start nor take an upload over USB any more: restore the "
        "bootloader with an SWD probe (docs/hardware.md#when-a-board-fails-to-flash)"
    ) in out


class PtyBoard(threading.Thread):
    """One board behind a pty named like a USB CDC port: sees the 1200-baud touch through tcgetattr and goes to its
    bootloader (in the listing); back in application mode (the stand-in bossac's doing) it answers ID? on the pty."""

    def __init__(self, rig: StandInRig, link: Path):
        super().__init__(daemon=True)
        self.rig, self.master, self.slave = rig, *pty.openpty()
        link.symlink_to(os.ttyname(self.slave))
        self.device, self.stop, self.touches = str(link), threading.Event(), 0

    def run(self):
        last = termios.tcgetattr(self.master)[5]
        while not self.stop.is_set():
            speed = termios.tcgetattr(self.master)[5]
            if speed == termios.B1200 and last != termios.B1200:  # the touch: re-enumerate as the bootloader
                self.touches += 1
                self.rig.write([p | {"pid": XIAO_PID_BOOT} for p in self.rig.read()])
            last = speed
            if select.select([self.master], [], [], 0.01)[0] and b"ID?" in os.read(self.master, 256):
                fw = identity_of(self.rig.flashed()["SN00"]["content"])
                os.write(self.master, f"MC role=cell addr=0x{fw.addr:02x} cell={fw.cell} fw=1.0\r\n".encode())


def test_a_pty_backed_board_through_the_real_touch_and_id_query(tmp_path, monkeypatch):
    """The real 1200-baud touch (pyserial) and the real `ID?` query on a pty listed by --ports-json."""
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    rig = StandInRig(tmp_path, bin_dir, monkeypatch, n=1)
    board = PtyBoard(rig, tmp_path / "ttyACM0")
    rig.write([p | {"device": board.device} for p in rig.read()])
    board.start()
    try:
        plan = bossac_plan(rig, tmp_path / "proj", only={1})
        f = rn.Flasher(rig.list_ports, expected_fw="1.0", touch=touch_1200, log_dir=tmp_path / "logs", out=print)
        f.bootloader_timeout = f.reappear_timeout = 10.0
        (o,) = f.flash(plan)
    finally:
        board.stop.set()
        board.join(5)
    assert o.ok, o.detail
    assert o.detail == f"cell 1 addr=0x10 fw=1.0 on {board.device}" and board.touches == 1
    assert [c["argv"][1] for c in calls(bin_dir) if "bossac" in c["argv"][0]] == [f"--port={board.device}"]
