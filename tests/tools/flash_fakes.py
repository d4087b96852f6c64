"""Stand-ins for the flashing tool's tests: fake boards and ports, a fake rig behind a mocked PlatformIO, and a
PlatformIO core dir and executables written into a temp dir (no hardware, no network)."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from types import SimpleNamespace

from metacell_tools.flash import inventory as inv
from metacell_tools.flash.boards import XIAO_PID_APP, XIAO_VID, Port
from metacell_tools.flash.identity import Identity, IdentityError, QueryResult
from metacell_tools.flash.plan import make_plan
from metacell_tools.flash.runner import Flasher


def fake_ports(n=17, pid=XIAO_PID_APP):
    ports = [Port(f"/dev/ttyACM{i}", XIAO_VID, pid, f"SN{i:02d}") for i in range(n)]
    ports.append(Port("/dev/ttyUSB0", 0x0403, 0x6001, "FTDI0"))  # not a XIAO: ignored
    return ports


def fake_inventory(n_cells=16):
    """Cells 1..n_cells on serials SN00.., the primary on the next serial (SN16 for the rig as built)."""
    boards = [inv.Board(f"SN{j - 1:02d}", "cell", j) for j in range(1, n_cells + 1)]
    return inv.validate(boards + [inv.Board(f"SN{max(n_cells, 16):02d}", "primary")], max(n_cells, 16))


def run_flash(rig, stop_on_error=False, tmp_path=None, **plan_kw):
    """(outcomes, lines printed) of flashing the fake rig's inventory on its ports (make_plan(..., **plan_kw)) with
    no waits; tmp_path: the log dir."""
    plan = make_plan(rig.boards, rig.ports, pio="pio", **plan_kw)
    lines = []
    f = Flasher(
        rig.list_ports,
        expected_fw=rig.fw,
        run=rig.run,
        query=rig.query,
        log_dir=tmp_path,
        sleep=lambda s: None,
        out=lines.append,
        reappear_timeout=0.0,
    )
    return f.flash(plan, stop_on_error=stop_on_error), lines


def write_ports_json(path, ports):
    path.write_text(
        json.dumps(
            [{"device": p.device, "vid": hex(p.vid), "pid": p.pid, "serial_number": p.serial_number} for p in ports]
        )
    )
    return path


class FakeRig:
    """Boards behind a fake `pio` and fake serial ports; records everything done to them."""

    def __init__(self, boards, ports, fail_upload=(), vanish=(), lie=None, silent=(), garbage=(), startup_error=()):
        self.boards, self.ports = boards, ports
        self.fail_upload, self.vanish, self.silent = set(fail_upload), set(vanish), set(silent)
        self.garbage, self.startup_error = set(garbage), set(startup_error)
        self.lie = lie or {}
        self.runs, self.flashed = [], {}
        self.fw = "1.0"

    def run(self, argv, env=None, **kw):
        self.runs.append((argv, env))
        port = argv[argv.index("--upload-port") + 1]
        serial = next(p.serial_number for p in self.ports if p.device == port)
        if serial in self.fail_upload:
            return SimpleNamespace(returncode=1, stdout="bossac: no device\n")
        flags = env.get("PLATFORMIO_BUILD_SRC_FLAGS", "")
        m = re.search(r"MC_CELL_INDEX=(\d+) -DMC_CELL_ADDR=0x([0-9a-f]+)", flags)
        role = argv[argv.index("-e") + 1]
        self.flashed[serial] = (role, int(m.group(1)) if m else None, int(m.group(2), 16) if m else None)
        return SimpleNamespace(returncode=0, stdout="SUCCESS\n")

    def list_ports(self):
        return [p for p in self.ports if p.serial_number not in self.vanish]

    def query(self, device):
        serial = next(p.serial_number for p in self.ports if p.device == device)
        if serial in self.silent:
            return QueryResult(None, [], [])
        if serial in self.garbage:
            raise IdentityError("fw must be major.minor")
        role, cell, addr = self.lie.get(serial, self.flashed[serial])
        ident = Identity(role, self.fw, cell, addr) if role == "cell" else Identity("primary", self.fw)
        errs = ["tick"] if serial in self.startup_error else []
        return QueryResult(ident, errs, [])


# ---- a PlatformIO core dir and stand-in executables in a temp dir -----------------------

PIO_BOSSAC_VERSION = "1.10700.190624"  # PlatformIO's tool-bossac as atmelsam 8.3.0 installs it for the XIAO


def write_exe(path: Path, body: str) -> Path:
    """An executable Python script (this interpreter) at path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"#!{sys.executable}\n{body}")
    path.chmod(0o755)
    return path


def core_dir(path: Path, atmelsam: bool = True, tool_bossac: bool = False) -> Path:
    """A PlatformIO core dir holding the atmelsam platform and (or not) PlatformIO's tool-bossac."""
    if atmelsam:
        (path / "platforms" / "atmelsam").mkdir(parents=True, exist_ok=True)
    (path / "packages").mkdir(parents=True, exist_ok=True)
    if tool_bossac:
        pkg = path / "packages" / "tool-bossac"
        pkg.mkdir(exist_ok=True)
        (pkg / "package.json").write_text(json.dumps({"name": "tool-bossac", "version": PIO_BOSSAC_VERSION}))
        write_exe(pkg / "bossac", "raise SystemExit('not to be run')\n")
    return path


# records its calls (calls.jsonl beside it: argv and the build's variables); a build writes firmware.bin and
# firmware.elf into the build dir, both holding the build's name and flags (so a stand-in board knows what it was
# given: objcopy of one is a copy); the build whose dir's name is in FAKE_PIO_FAIL fails with PlatformIO's output of
# an offline machine, the one in FAKE_PIO_NO_BIN leaves no firmware.bin
STANDIN_PIO = r"""
import json, os, pathlib, sys
args = sys.argv[1:]
log = pathlib.Path(__file__).with_name("calls.jsonl")
keys = ("PLATFORMIO_BUILD_DIR", "PLATFORMIO_BUILD_SRC_FLAGS", "PIO", "PIO_OFFLINE_WORK")
with log.open("a") as f:
    f.write(json.dumps({"argv": [sys.argv[0]] + args, **{k: os.environ.get(k) for k in keys}}) + "\n")
assert args[0] == "run" and "-e" in args, args
env = args[args.index("-e") + 1]
build = pathlib.Path(os.environ["PLATFORMIO_BUILD_DIR"])
print(f"Processing {env} (platform: atmelsam@8.3.0; board: seeed_xiao; framework: arduino)")
print("-" * 80)
if build.name in os.environ.get("FAKE_PIO_FAIL", "").split(","):
    print("Platform Manager: Installing atmelsam @ 8.3.0")
    print("Error: HTTPClientError: ")
    sys.exit(1)
out = build / env
out.mkdir(parents=True, exist_ok=True)
if build.name not in os.environ.get("FAKE_PIO_NO_BIN", "").split(","):
    (out / "firmware.bin").write_text(f"{build.name} {os.environ.get('PLATFORMIO_BUILD_SRC_FLAGS', '')}")
(out / "firmware.elf").write_text(f"{build.name} {os.environ.get('PLATFORMIO_BUILD_SRC_FLAGS', '')}")
print(f"Building {out}/firmware.bin")
print("=" * 25 + " [SUCCESS] Took 1.00 seconds " + "=" * 25)
"""

# bossac 1.9.1 as the flash tool must call it; FAKE_PORTS is the port listing it shares with the tool: the port must
# be a listed bootloader port (else what the real bossac says about a port without SAM-BA behind it); a good upload
# records the file's content in flashed.json beside it and brings the board back in application mode, on its original
# device name (an upload below 0x2000 leaves it gone: the bootloader is overwritten); FAKE_BOSSAC_FAIL lists serial
# numbers whose upload fails as a real one can (FAKE_BOSSAC_FAIL_ONCE: only their first upload), leaving the board in
# its bootloader; FAKE_BOSSAC_UNPLUG's boards leave the listing during their upload, which fails
STANDIN_BOSSAC = r"""
import json, os, pathlib, re, sys
args = sys.argv[1:]
here = pathlib.Path(__file__).parent
with (here / "calls.jsonl").open("a") as f:
    clock = {k: os.environ[k] for k in ("FAKETIME", "LD_PRELOAD") if k in os.environ}
    f.write(json.dumps({"argv": [sys.argv[0]] + args, **({"clock": clock} if clock else {})}) + "\n")
want = ["--usb-port=1", "--info", "--offset=OFFSET", "--erase", "--write", "--verify", "--reset"]
port = args[0][len("--port="):] if args and args[0].startswith("--port=") else None
offset = re.fullmatch(r"--offset=0x([0-9a-f]+)", args[3]).group(1) if len(args) == 9 else None
if port is None or offset is None or [re.sub("=0x.*", "=OFFSET", a) for a in args[1:8]] != want:
    print("bossac: extra arguments found", file=sys.stderr)
    sys.exit(1)
fw = pathlib.Path(args[8])
listing = pathlib.Path(os.environ["FAKE_PORTS"])
ports = json.loads(listing.read_text())
me = next((p for p in ports if p["device"] == port and p["pid"] == 0x002F), None)
if me is None:
    print(f"No device found on {port}", file=sys.stderr)
    sys.exit(1)
print("Device       : ATSAMD21G18A")
print("Version      : v1.1 [Arduino:XYZ] Nov 27 2019 16:35:08")
if me["serial_number"] in os.environ.get("FAKE_BOSSAC_UNPLUG", "").split(","):  # the cable pulled mid-write
    listing.write_text(json.dumps([p for p in ports if p is not me]))
    print(f"Write {fw.stat().st_size} bytes to flash (1 pages)")
    print("SAM-BA operation failed", file=sys.stderr)
    sys.exit(1)
once = here / f"failed-once-{me['serial_number']}"
first = me["serial_number"] in os.environ.get("FAKE_BOSSAC_FAIL_ONCE", "").split(",") and not once.exists()
if first:
    once.write_text("")
if first or me["serial_number"] in os.environ.get("FAKE_BOSSAC_FAIL", "").split(","):
    print(f"Erase flash\nDone in 0.7 seconds\nWrite {fw.stat().st_size} bytes to flash (1 pages)")
    print("SAM-BA operation failed", file=sys.stderr)
    sys.exit(1)
print(f"Write {fw.stat().st_size} bytes to flash (1 pages)\nVerify successful\nDone in 0.1 seconds")
flashed = here / "flashed.json"
done = json.loads(flashed.read_text()) if flashed.exists() else {}
done[me["serial_number"]] = {"content": fw.read_bytes().decode("latin-1"), "offset": int(offset, 16)}
flashed.write_text(json.dumps(done))
if int(offset, 16) >= 0x2000:
    me["pid"], me["device"] = 0x802F, me.pop("app_device", me["device"])
else:
    ports.remove(me)
tmp = listing.with_suffix(".tmp")
tmp.write_text(json.dumps(ports))
tmp.replace(listing)
"""


def pio_tools(tmp_path: Path, monkeypatch, uploader: str = "pio", tree: Path | None = None) -> Path:
    """This test's machine: a bin dir (the whole PATH) with a stand-in pio (and bossac when uploader is "bossac"),
    a PlatformIO core dir with atmelsam (and PlatformIO's tool-bossac when uploader is "pio"), MC_PIO_TREE = tree."""
    bin_dir = tmp_path / "bin"
    write_exe(bin_dir / "pio", STANDIN_PIO)
    if uploader == "bossac":
        write_exe(bin_dir / "bossac", STANDIN_BOSSAC)
    core = core_dir(tmp_path / "core", atmelsam=uploader != "none", tool_bossac=uploader == "pio")
    monkeypatch.setenv("PATH", str(bin_dir))
    monkeypatch.setenv("PLATFORMIO_CORE_DIR", str(core))
    for var in (
        "MC_PIO_TREE",
        "MC_PIO",
        "MC_BOSSAC",
        "FAKE_PIO_FAIL",
        "FAKE_PIO_NO_BIN",
        "FAKE_BOSSAC_FAIL",
        "FAKE_BOSSAC_FAIL_ONCE",
    ):
        monkeypatch.delenv(var, raising=False)
    if tree is not None:
        monkeypatch.setenv("MC_PIO_TREE", str(tree))
    return bin_dir


def calls(bin_dir: Path) -> list[dict]:
    """What the stand-ins in bin_dir were asked to do, in order."""
    log = bin_dir / "calls.jsonl"
    return [json.loads(ln) for ln in log.read_text().splitlines()] if log.exists() else []
