"""Flashing tool: address map, identity wire format (against the C formatter), inventory, plan, failure paths."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import inventory as inv
from metacell_tools.flash import runner as rn
from metacell_tools.flash.addresses import CELL_ADDRESSES, RESERVED, address_cell, cell_address
from metacell_tools.flash.boards import (
    XIAO_PID_APP,
    XIAO_PID_BOOT,
    XIAO_VID,
    Port,
    PortListError,
    ports_from_json,
    xiao_ports,
)
from metacell_tools.flash.identity import (
    REQUEST,
    SAFE_BAUD,
    Identity,
    IdentityError,
    QueryResult,
    expected_fw_version,
    open_serial,
    parse_identity,
    query_identity,
)
from metacell_tools.flash.plan import PlanError, describe, make_plan, parse_only

ROOT = Path(__file__).resolve().parents[2]
IDENT_H = ROOT / "src" / "common" / "mc_ident.h"
IDENT_C = ROOT / "src" / "common" / "mc_ident.c"


# ---- the C side of the identity format, built on the host -----------------------


@pytest.fixture(scope="module")
def ident_c(tmp_path_factory):
    """src/common/mc_ident.c compiled with -std=c99 -Wall -Wextra -Werror via cffi."""
    import cffi

    from host_emulator import firmware

    ffi = cffi.FFI()
    ffi.cdef(firmware.cdef_source([IDENT_H]))
    ffi.set_source(
        "_mc_ident_test",
        f'#include "{IDENT_H}"',
        sources=[str(IDENT_C)],
        extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"],
    )
    so = ffi.compile(tmpdir=str(tmp_path_factory.mktemp("ident")), verbose=False)
    spec = importlib.util.spec_from_file_location("_mc_ident_test", so)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib


def c_format(ident_c, role, cell, addr, fw):
    ffi, lib = ident_c
    buf = ffi.new("char[]", lib.MC_IDENT_LINE_MAX)
    n = lib.mc_ident_format(buf, lib.MC_IDENT_LINE_MAX, role, cell, addr, fw)
    return None if n < 0 else ffi.string(buf, n).decode("ascii")


def test_address_map_is_one_to_one_and_unreserved():
    assert sorted(CELL_ADDRESSES) == list(range(1, 17))
    addrs = list(CELL_ADDRESSES.values())
    assert len(set(addrs)) == 16 and not set(addrs) & RESERVED
    assert all(0x08 <= a <= 0x77 for a in addrs)
    assert cell_address(1) == 0x10 and cell_address(16) == 0x1F
    assert all(address_cell(cell_address(j)) == j for j in range(1, 17))
    for bad in (0, 17, -1, True, "3", 2.0):
        with pytest.raises(ValueError):
            cell_address(bad)
    with pytest.raises(ValueError, match="belongs to no cell"):
        address_cell(0x20)


def test_prompt_example_line_parses():
    ident = parse_identity("MC role=cell addr=0x10 cell=1 fw=1.0\r\n")
    assert ident == Identity("cell", "1.0", 1, 0x10)
    assert parse_identity("MC role=primary fw=1.0") == Identity("primary", "1.0")
    assert parse_identity("MC role=cell addr=none cell=0 fw=2.3") == Identity("cell", "2.3", 0, None)


@pytest.mark.parametrize(
    "line, why",
    [
        ("MC role=cell addr=0x10 fw=1.0", "cell must be"),
        ("MC role=cell addr=0x10 cell=17 fw=1.0", "cell must be"),
        ("MC role=cell addr=0x05 cell=1 fw=1.0", "reserved"),
        ("MC role=cell addr=0x7c cell=1 fw=1.0", "reserved"),
        ("MC role=cell addr=none cell=3 fw=1.0", "inconsistent"),
        ("MC role=cell addr=0x12 cell=0 fw=1.0", "inconsistent"),
        ("MC role=cell addr=18 cell=3 fw=1.0", "addr must be"),
        ("MC role=robot fw=1.0", "role must be"),
        ("MC role=primary fw=1", "fw must be"),
        ("MC role=primary fw=01.0", "fw must be"),
        ("MC role=cell addr=0x12 cell=03 fw=1.0", "cell must be"),
        ("MC role=primary fw=1.300", "fw must be"),
        ("MC role=primary addr=0x10 fw=1.0", "primary reply carries"),
        ("MC role=primary role=cell fw=1.0", "repeated"),
        ("MC role=primary fw", "bad field"),
        ("ID?", "not an identity line"),
    ],
)
def test_malformed_identity_lines_are_refused_with_the_reason(line, why):
    with pytest.raises(IdentityError, match=why):
        parse_identity(line)


@settings(max_examples=400, deadline=None)
@given(role=st.integers(0, 3), cell=st.integers(-2, 18), addr=st.integers(-1, 0x82), fw=st.integers(0, 0xFFFF))
def test_c_formatter_and_python_parser_agree(ident_c, role, cell, addr, fw):
    line = c_format(ident_c, role, cell, addr, fw)
    valid_cell = role == 1 and 0 <= cell <= 16 and (addr == 0 if cell == 0 else 0x08 <= addr <= 0x77)
    assert (line is not None) == (valid_cell or role == 2)
    if line is None:
        return
    assert line.endswith("\r\n") and len(line) < ident_c[1].MC_IDENT_LINE_MAX
    got = parse_identity(line)
    fw_s = f"{fw >> 8}.{fw & 0xFF}"
    if role == 2:
        assert got == Identity("primary", fw_s)
    else:
        assert got == Identity("cell", fw_s, cell, addr if cell else None)


def test_c_formatter_refuses_a_short_buffer_and_leaves_it_untouched(ident_c):
    ffi, lib = ident_c
    buf = ffi.new("char[]", b"Z" * 10)
    assert lib.mc_ident_format(buf, 10, 1, 3, 0x12, 0x0100) == -1
    assert ffi.buffer(buf)[:10] == b"Z" * 10
    assert lib.mc_ident_format(ffi.NULL, 64, 2, 0, 0, 0x0100) == -1


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.sampled_from([b"I", b"D", b"?", b"\r", b"\n", b"x", b"ID?", b"ID?\r", b"IID?", b"ID?\n"]), max_size=40)
)
def test_c_request_matcher_fires_exactly_on_lines_equal_to_ID(ident_c, chunks):
    ffi, lib = ident_c
    stream = b"".join(chunks)
    rx = ffi.new("mc_ident_rx_t *")
    lib.mc_ident_rx_init(rx)
    fired = [i for i, byte in enumerate(stream) if lib.mc_ident_rx_feed(rx, byte)]
    # reference: positions of line terminators whose preceding line is exactly b"ID?"
    expect, start = [], 0
    for i, byte in enumerate(stream):
        if byte in b"\r\n":
            if stream[start:i] == b"ID?":
                expect.append(i)
            start = i + 1
    assert fired == expect


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_parser_never_fails_other_than_with_identity_error(text):
    try:
        got = parse_identity("MC " + text)
    except IdentityError:
        return
    assert got.role in ("cell", "primary")


def test_expected_fw_version_comes_from_the_library_header(tmp_path):
    text = (ROOT / "lib/metacell/src/mc_cell.h").read_text()
    v = int(re.search(r"#define\s+MC_FW_VERSION\s+(\S+)", text).group(1), 0)
    assert expected_fw_version() == f"{v >> 8}.{v & 0xFF}"
    h = tmp_path / "x.h"
    h.write_text("#define MC_FW_VERSION 0x0203\n")
    assert expected_fw_version(h) == "2.3"
    h.write_text("nothing\n")
    with pytest.raises(RuntimeError):
        expected_fw_version(h)


# ---- fake boards ------------------------------------------------------------------


def fake_ports(n=17, pid=XIAO_PID_APP):
    ports = [Port(f"/dev/ttyACM{i}", XIAO_VID, pid, f"SN{i:02d}") for i in range(n)]
    ports.append(Port("/dev/ttyUSB0", 0x0403, 0x6001, "FTDI0"))  # not a XIAO: ignored
    return ports


def fake_inventory(n_cells=16):
    boards = [inv.Board(f"SN{j - 1:02d}", "cell", j) for j in range(1, n_cells + 1)]
    return inv.validate(boards + [inv.Board("SN16", "primary")])


def write_ports_json(path, ports):
    path.write_text(
        json.dumps(
            [{"device": p.device, "vid": hex(p.vid), "pid": p.pid, "serial_number": p.serial_number} for p in ports]
        )
    )
    return path


def test_ports_json_reading_and_errors(tmp_path):
    ports = ports_from_json(write_ports_json(tmp_path / "p.json", fake_ports(3)))
    assert [p.device for p in xiao_ports(ports)] == ["/dev/ttyACM0", "/dev/ttyACM1", "/dev/ttyACM2"]
    assert ports[0].vid == XIAO_VID and ports[0].is_xiao and not ports[-1].is_xiao
    for bad in (
        '{"device": "x"}',
        '[{"vid": 1}]',
        '[{"device": "x", "vid": "zz"}]',
        '[{"device": "x", "serial_number": 5}]',
        "not json",
    ):
        (tmp_path / "b.json").write_text(bad)
        with pytest.raises(PortListError):
            ports_from_json(tmp_path / "b.json")


def test_natural_port_order():
    ports = [Port(f"/dev/ttyACM{i}", XIAO_VID, XIAO_PID_APP, str(i)) for i in (10, 2, 1)]
    assert [p.device for p in xiao_ports(ports)] == ["/dev/ttyACM1", "/dev/ttyACM2", "/dev/ttyACM10"]


# ---- inventory ----------------------------------------------------------------------


def test_two_boards_claiming_one_address_are_refused(tmp_path):
    with pytest.raises(inv.InventoryError, match=r"two boards claim cell 3 \(address 0x12\): A, B"):
        inv.validate([inv.Board("A", "cell", 3), inv.Board("B", "cell", 3)])
    path = tmp_path / "boards.json"
    path.write_text(
        json.dumps(
            {
                "format": inv.FORMAT,
                "boards": [{"serial": "A", "role": "cell", "cell": 3}, {"serial": "B", "role": "cell", "cell": 3}],
            }
        )
    )
    with pytest.raises(inv.InventoryError, match="two boards claim cell 3"):
        inv.load(path)


@pytest.mark.parametrize(
    "boards, why",
    [
        ([inv.Board("A", "cell", 1), inv.Board("A", "cell", 2)], "listed twice"),
        ([inv.Board("A", "primary"), inv.Board("B", "primary")], "more than one primary"),
        ([inv.Board("A", "cell", 0)], "cell must be 1..16"),
        ([inv.Board("A", "cell", 17)], "cell must be 1..16"),
        ([inv.Board("A", "cell", True)], "cell must be 1..16"),
        ([inv.Board("A", "spare")], "role must be"),
        ([inv.Board("", "cell", 1)], "non-empty"),
        ([inv.Board("A", "primary", 2)], "must not carry"),
    ],
)
def test_inventory_validation(boards, why):
    with pytest.raises(inv.InventoryError, match=why):
        inv.validate(boards)


def test_inventory_roundtrip_and_assign(tmp_path):
    path = tmp_path / "rig" / "boards.json"
    boards = fake_inventory()
    inv.save(path, boards)
    assert inv.load(path) == boards
    before = path.read_text()
    with pytest.raises(inv.InventoryError, match=r"cell 4 \(0x13\) is already board SN03"):
        inv.assign(boards, "NEW", "4")
    with pytest.raises(inv.InventoryError):
        inv.save(path, boards + [inv.Board("X", "cell", 4)])  # invalid set never written
    assert path.read_text() == before
    swapped = inv.assign(boards, "NEW", "4", replace=True)
    assert [b.serial for b in swapped if b.cell == 4] == ["NEW"]
    assert "SN03" not in {b.serial for b in swapped}
    moved = inv.assign(boards, "SN00", "primary", replace=True)  # a board changes role
    assert [b.serial for b in moved if b.role == "primary"] == ["SN00"]
    assert not any(b.cell == 1 for b in moved)
    for bad in ("0", "17", "x"):
        with pytest.raises(inv.InventoryError):
            inv.assign(boards, "NEW", bad)
    for bad in (
        "[]",
        '{"format": "other", "boards": []}',
        json.dumps({"format": inv.FORMAT, "boards": [{"serial": "A", "role": "cell", "cell": 1, "colour": "red"}]}),
    ):
        path.write_text(bad)
        with pytest.raises(inv.InventoryError):
            inv.load(path)
    with pytest.raises(inv.InventoryError, match="no inventory"):
        inv.load(tmp_path / "absent.json")


def test_inventory_cli_assigns_the_single_new_board(tmp_path, capsys):
    ports = write_ports_json(tmp_path / "p.json", fake_ports(2))
    path = tmp_path / "b.json"
    args = ["inventory", "--inventory", str(path), "--ports-json", str(ports)]
    assert cli.main(args + ["--assign", "5"]) == cli.EXIT_USAGE  # two new boards: ambiguous
    assert not path.exists()
    assert cli.main(args + ["--assign", "5", "--serial", "SN01"]) == 0
    assert cli.main(args + ["--assign", "primary"]) == 0  # SN00 is the only new one
    assert {(b.serial, b.role, b.cell) for b in inv.load(path)} == {("SN01", "cell", 5), ("SN00", "primary", None)}
    assert cli.main(args + ["--assign", "5", "--serial", "SN00"]) == cli.EXIT_USAGE
    assert "already board SN01" in capsys.readouterr().err


# ---- plan ------------------------------------------------------------------------------


def test_plan_lists_17_correct_upload_commands(tmp_path, capsys, monkeypatch):
    """Acceptance: 17 fake boards -> 17 upload commands, each with its own port and address."""

    def no_hardware(*a, **k):
        raise AssertionError("plan must not touch hardware or run anything")

    monkeypatch.setattr(subprocess, "run", no_hardware)
    monkeypatch.setattr("serial.Serial", no_hardware)
    ports = fake_ports(17)
    inv.save(tmp_path / "b.json", fake_inventory())
    rc = cli.main(
        [
            "plan",
            "--inventory",
            str(tmp_path / "b.json"),
            "--pio",
            "pio",
            "--project",
            "/rig/proj",
            "--ports-json",
            str(write_ports_json(tmp_path / "p.json", ports)),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    cmds = [ln.strip() for ln in out.splitlines() if " pio run " in f" {ln.strip()}"]
    assert len(cmds) == 17
    for j in range(1, 17):
        a = cell_address(j)
        assert cmds[j - 1] == (
            f"PLATFORMIO_BUILD_DIR=/rig/proj/.pio/build-cell{j:02d} "
            f"PLATFORMIO_BUILD_SRC_FLAGS='-DMC_CELL_INDEX={j} -DMC_CELL_ADDR=0x{a:02x}' "
            f"pio run -d /rig/proj -e cell -t upload --upload-port /dev/ttyACM{j - 1}"
        )
    assert cmds[16] == (
        "PLATFORMIO_BUILD_DIR=/rig/proj/.pio/build-primary "
        "PLATFORMIO_BUILD_SRC_FLAGS='' "
        "pio run -d /rig/proj -e primary -t upload --upload-port /dev/ttyACM16"
    )
    assert "/dev/ttyUSB0" not in out


def test_plan_follows_serial_numbers_not_port_order():
    ports = fake_ports(17)[::-1]  # enumeration order shuffled
    ports = [Port(f"/dev/ttyACM{99 - i}", p.vid, p.pid, p.serial_number) for i, p in enumerate(ports)]
    plan = make_plan(fake_inventory(), ports, pio="pio")
    by_serial = {p.serial_number: p.device for p in ports}
    assert [s.port.device for s in plan.steps] == [by_serial[s.board.serial] for s in plan.steps]
    assert [s.board.cell for s in plan.steps[:16]] == list(range(1, 17))


def test_missing_board_is_a_clear_error_unless_skipped():
    ports = [p for p in fake_ports(17) if p.serial_number != "SN06"]  # cell 7 unplugged
    with pytest.raises(PlanError, match=r"cell 7 \(0x16\) serial SN06 is not connected"):
        make_plan(fake_inventory(), ports)
    plan = make_plan(fake_inventory(), ports, skip_missing=True)
    assert len(plan.steps) == 16 and [b.cell for b in plan.missing] == [7]
    assert "SKIPPED (not connected): cell 7" in describe(plan)


def test_missing_board_cli_exit_code(tmp_path, capsys):
    inv.save(tmp_path / "b.json", fake_inventory())
    ports = write_ports_json(tmp_path / "p.json", fake_ports(16))  # the primary is absent
    rc = cli.main(["plan", "--inventory", str(tmp_path / "b.json"), "--ports-json", str(ports)])
    assert rc == cli.EXIT_USAGE
    assert "primary serial SN16 is not connected" in capsys.readouterr().err


def test_unknown_boards_are_left_alone_and_only_selects():
    ports = fake_ports(17) + [Port("/dev/ttyACM40", XIAO_VID, XIAO_PID_APP, "STRANGER")]
    plan = make_plan(fake_inventory(), ports, only=parse_only("2-3,primary"))
    assert [s.board.name for s in plan.steps] == ["cell 2 (0x11)", "cell 3 (0x12)", "primary"]
    assert [p.serial_number for p in plan.unknown] == ["STRANGER"]
    assert len(plan.unselected) == 14
    assert parse_only("1,1-2") == {1, 2}
    for bad in ("0", "15-17", "3-1", "x", ",", "primary-2"):
        with pytest.raises(PlanError):
            parse_only(bad)
    with pytest.raises(PlanError, match="does not have: primary"):
        make_plan(fake_inventory()[:16], fake_ports(17), only={"primary"})


def test_one_serial_on_two_ports_is_refused_and_bootloader_boards_are_planned():
    ports = fake_ports(17) + [Port("/dev/ttyACM50", XIAO_VID, XIAO_PID_BOOT, "SN03")]
    with pytest.raises(PlanError, match="serial SN03 on both /dev/ttyACM3 and /dev/ttyACM50"):
        make_plan(fake_inventory(), ports)
    ports = [
        Port(p.device, p.vid, XIAO_PID_BOOT if p.serial_number == "SN03" else p.pid, p.serial_number)
        for p in fake_ports(17)
    ]
    plan = make_plan(fake_inventory(), ports)
    assert len(plan.steps) == 17 and "[bootloader]" in describe(plan)


@pytest.mark.skipif(not (shutil.which("pio") or (ROOT / ".venv/bin/pio").exists()), reason="PlatformIO not installed")
def test_planned_environment_reaches_the_platformio_configuration():
    """The per-cell flags really land in env:cell (pio project config works offline)."""
    import os

    pio = shutil.which("pio") or str(ROOT / ".venv/bin/pio")
    plan = make_plan(fake_inventory(), fake_ports(17), pio=pio, only={12, "primary"})

    def config(step):
        stray = {"PLATFORMIO_BUILD_SRC_FLAGS": "-DMC_CELL_INDEX=3 -DMC_CELL_ADDR=0x12"}
        env = {**os.environ, **stray, **dict(step.env_vars)}
        res = subprocess.run(
            [pio, "project", "config", "-d", str(ROOT), "--json-output"],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert res.returncode == 0, res.stderr
        return {sec: dict(opts) for sec, opts in json.loads(res.stdout)}

    conf = config(plan.steps[0])
    flags = " ".join(conf["env:cell"]["build_src_flags"])
    assert f"-DMC_CELL_INDEX=12 -DMC_CELL_ADDR=0x{cell_address(12):02x}" in flags
    assert "MC_CELL_INDEX=3" not in flags  # the stray value is overridden
    assert conf["env:cell"]["build_src_filter"] == ["+<cell/> +<common/>"]
    assert conf["env:native"]["test_build_src"] is False
    conf = config(plan.steps[1])  # primary: cell flags cancelled
    assert "MC_CELL" not in " ".join(conf["env:primary"].get("build_src_flags", []))
    assert conf["env:primary"]["build_src_filter"] == ["+<primary/> +<common/>"]


# ---- flashing with mocked PlatformIO and serial -----------------------------------------


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


def run_flash(rig, stop_on_error=False, tmp_path=None):
    plan = make_plan(rig.boards, rig.ports, pio="pio")
    lines = []
    f = rn.Flasher(
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


def test_flash_all_boards_ok(tmp_path):
    rig = FakeRig(fake_inventory(), fake_ports(17))
    outcomes, _ = run_flash(rig, tmp_path=tmp_path)
    assert [o.status for o in outcomes] == [rn.OK] * 17
    assert rig.flashed["SN04"] == ("cell", 5, 0x14) and rig.flashed["SN16"] == ("primary", None, None)
    assert "17 of 17 board(s) flashed and verified" in rn.summary(outcomes)
    assert (tmp_path / "cell05.log").read_text().startswith("$ PLATFORMIO_BUILD_DIR=")


@pytest.mark.parametrize("stop", [False, True])
def test_failed_upload_names_the_board_and_leaves_the_others(tmp_path, stop):
    rig = FakeRig(fake_inventory(), fake_ports(17), fail_upload={"SN04"})
    outcomes, lines = run_flash(rig, stop_on_error=stop, tmp_path=tmp_path)
    bad = [o for o in outcomes if not o.ok]
    assert bad[0].step.board.name == "cell 5 (0x14)" and bad[0].status == rn.UPLOAD_FAILED
    assert "pio exited with 1" in bad[0].detail
    assert any("FAILED: upload failed" in ln for ln in lines)
    assert "FAILED: cell 5 (0x14)" in rn.summary(outcomes)
    if stop:  # nothing after cell 5 was touched
        assert len(rig.runs) == 5 and set(rig.flashed) == {f"SN{i:02d}" for i in range(4)}
        assert [o.status for o in outcomes[5:]] == [rn.NOT_RUN] * 12
    else:  # every other board flashed and verified
        assert len(rig.runs) == 17 and len(bad) == 1 and "SN04" not in rig.flashed


@pytest.mark.parametrize("case", ["failed upload", "skipped missing", "all ok"])
def test_flash_cli_exit_code(tmp_path, monkeypatch, capsys, case):
    n_ports = 16 if case == "skipped missing" else 17  # port 16 is the primary's
    rig = FakeRig(fake_inventory(), fake_ports(n_ports), fail_upload={"SN10"} if case == "failed upload" else ())
    monkeypatch.setattr(
        cli,
        "Flasher",
        lambda lister, **kw: rn.Flasher(
            rig.list_ports,
            run=rig.run,
            query=rig.query,
            sleep=lambda s: None,
            **{**kw, "reappear_timeout": 0.0, "expected_fw": "1.0"},
        ),
    )
    inv.save(tmp_path / "b.json", fake_inventory())
    args = [
        "flash",
        "--inventory",
        str(tmp_path / "b.json"),
        "--log-dir",
        str(tmp_path),
        "--ports-json",
        str(write_ports_json(tmp_path / "p.json", rig.ports)),
    ]
    rc = cli.main(args + (["--skip-missing"] if case == "skipped missing" else []))
    out = capsys.readouterr().out
    if case == "failed upload":
        assert rc == cli.EXIT_FAILED
        assert "16 of 17 board(s) flashed and verified; FAILED: cell 11 (0x1a)" in out
    elif case == "skipped missing":
        assert rc == cli.EXIT_FAILED
        assert "16 of 16 board(s) flashed and verified" in out
        assert "NOT FLASHED (not connected): primary serial SN16" in out
    else:
        assert rc == cli.EXIT_OK and "17 of 17 board(s) flashed and verified" in out


def test_identity_mismatch_after_upload(tmp_path):
    rig = FakeRig(fake_inventory(), fake_ports(17), lie={"SN02": ("cell", 4, 0x13)})
    outcomes, _ = run_flash(rig, tmp_path=tmp_path)
    bad = [o for o in outcomes if not o.ok]
    assert len(bad) == 1 and bad[0].status == rn.MISMATCH
    assert bad[0].detail == "expected cell 3 addr=0x12 fw=1.0, board says cell 4 addr=0x13 fw=1.0"


def test_wrong_firmware_version_is_a_mismatch(tmp_path):
    rig = FakeRig(fake_inventory(2)[:1], fake_ports(1))
    plan = make_plan(rig.boards, rig.ports)
    f = rn.Flasher(
        rig.list_ports,
        expected_fw="9.9",
        run=rig.run,
        query=rig.query,
        log_dir=tmp_path,
        out=lambda s: None,
        reappear_timeout=0.0,
    )
    (o,) = f.flash(plan)
    assert o.status == rn.MISMATCH and "fw=9.9" in o.detail


@pytest.mark.parametrize(
    "kind, status, text",
    [
        ("vanish", rn.GONE, "no application port with serial SN07"),
        ("silent", rn.NO_IDENTITY, "no answer to ID?"),
        ("garbage", rn.NO_IDENTITY, "malformed reply"),
        ("startup_error", rn.MISMATCH, "start-up error: tick"),
    ],
)
def test_board_that_does_not_verify(tmp_path, kind, status, text):
    rig = FakeRig(fake_inventory(), fake_ports(17), **{kind: {"SN07"}})
    outcomes, _ = run_flash(rig, tmp_path=tmp_path)
    bad = [o for o in outcomes if not o.ok]
    assert [(o.step.board.cell, o.status) for o in bad] == [(8, status)]
    assert text in bad[0].detail


def test_pio_missing_or_hanging_is_an_upload_failure(tmp_path):
    rig = FakeRig(fake_inventory(1)[:1], fake_ports(1))
    plan = make_plan(rig.boards, rig.ports)

    def missing(*a, **k):
        raise FileNotFoundError("pio")

    def hangs(*a, **k):
        raise subprocess.TimeoutExpired("pio", 1)

    for run, text in ((missing, "cannot run pio"), (hangs, "did not finish")):
        f = rn.Flasher(
            rig.list_ports, expected_fw="1.0", run=run, query=rig.query, log_dir=tmp_path, out=lambda s: None
        )
        (o,) = f.flash(plan)
        assert o.status == rn.UPLOAD_FAILED and text in o.detail


def test_wait_for_app_port_ignores_the_bootloader_port():
    seq = [
        [Port("/dev/ttyACM3", XIAO_VID, XIAO_PID_BOOT, "S")],
        [],
        [Port("/dev/ttyACM4", XIAO_VID, XIAO_PID_APP, "S")],
    ]
    t = [0.0]
    got = rn.wait_for_app_port(
        "S",
        lambda: seq.pop(0) if seq else [],
        timeout=10,
        sleep=lambda s: t.__setitem__(0, t[0] + s),
        clock=lambda: t[0],
    )
    assert got.device == "/dev/ttyACM4"
    assert (
        rn.wait_for_app_port("S", lambda: [], timeout=2, sleep=lambda s: t.__setitem__(0, t[0] + s), clock=lambda: t[0])
        is None
    )


# ---- the serial side of the identity query ----------------------------------------------


class FakeSerial:
    def __init__(self, replies):
        self.replies, self.written, self.closed = list(replies), [], False

    def write(self, data):
        self.written.append(data)

    def readline(self):
        return self.replies.pop(0) if self.replies else b""

    def close(self):
        self.closed = True


def test_query_skips_noise_collects_errors_and_closes():
    fake = FakeSerial([b"", b"t1230\r", b"MC error=tick\r\n", b"MC role=cell addr=0x13 ", b"cell=4 fw=1.0\r\n"])
    t = iter(range(1000))
    q = query_identity("/dev/x", opener=lambda d: fake, clock=lambda: next(t) * 0.01)
    assert q.identity == Identity("cell", "1.0", 4, 0x13)
    assert q.errors == ["tick"] and "t1230" in q.raw
    assert fake.written[0] == REQUEST == b"ID?\r\n" and fake.closed


def test_query_times_out_resending_the_request():
    fake = FakeSerial([])
    t = iter(range(10000))
    q = query_identity("/dev/x", opener=lambda d: fake, timeout=2.0, retry_every=0.5, clock=lambda: next(t) * 0.1)
    assert q.identity is None and fake.closed
    assert 3 <= len(fake.written) <= 5


def test_serial_is_never_opened_at_1200_baud(monkeypatch):
    seen = {}
    monkeypatch.setattr("serial.Serial", lambda dev, **kw: seen.update(kw, dev=dev))
    open_serial("/dev/ttyACM0")
    assert seen["baudrate"] == SAFE_BAUD != 1200


def test_identify_flags_two_boards_claiming_one_address(tmp_path, capsys):
    ports = fake_ports(3)
    answers = {
        "/dev/ttyACM0": Identity("cell", "1.0", 3, 0x12),
        "/dev/ttyACM1": Identity("cell", "1.0", 3, 0x12),
        "/dev/ttyACM2": Identity("primary", "1.0"),
    }
    args = SimpleNamespace(inventory=str(tmp_path / "none.json"))
    rc = cli.cmd_identify(
        args, lambda: ports, lambda m, err=False: print(m), query=lambda d: QueryResult(answers[d], [], [])
    )
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED
    assert "two boards claim address 0x12: /dev/ttyACM0 (serial SN00), /dev/ttyACM1 (serial SN01)" in out
    answers["/dev/ttyACM1"] = Identity("cell", "1.0", 4, 0x13)
    assert (
        cli.cmd_identify(
            args, lambda: ports, lambda m, err=False: None, query=lambda d: QueryResult(answers[d], [], [])
        )
        == cli.EXIT_OK
    )


# ---- the flags the tool passes satisfy the firmware's own build-time checks -------------


def _cell_config(defines: list[str]) -> subprocess.CompletedProcess:
    cc = shutil.which("cc") or shutil.which("gcc")
    return subprocess.run(
        [cc, "-fsyntax-only", "-x", "c", "-", "-I", str(ROOT / "src" / "cell"), *defines],
        input='#include "cell_config.h"\n',
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="no host C compiler")
def test_planned_cell_flags_pass_cell_config_and_bad_ones_do_not():
    plan = make_plan(fake_inventory(), fake_ports(17))
    for step in plan.steps[:16]:
        flags = dict(step.env_vars)["PLATFORMIO_BUILD_SRC_FLAGS"].split()
        res = _cell_config(flags)
        assert res.returncode == 0, (flags, res.stderr)
    assert _cell_config([]).returncode == 0  # unaddressed image
    for bad, why in (
        (["-DMC_CELL_INDEX=17", "-DMC_CELL_ADDR=0x20"], "MC_CELL_INDEX must be"),
        (["-DMC_CELL_INDEX=3", "-DMC_CELL_ADDR=0x05"], "non-reserved"),
        (["-DMC_CELL_INDEX=3", "-DMC_CELL_ADDR=0x78"], "non-reserved"),
        (["-DMC_CELL_ADDR=0x12"], "without MC_CELL_INDEX"),
        (["-DMC_CTRL_RATE_HZ=60000"], "MC_CTRL_RATE_HZ"),
        (["-DMC_PWM_TOP=5000"], "MC_PWM_TOP"),
    ):
        res = _cell_config(bad)
        assert res.returncode != 0 and why in res.stderr, (bad, res.stderr)


# ---- the PlatformIO post-build hook -------------------------------------------------------

WANT_ARGS = {
    "cell": ["cell", "--root", "TC3_Handler", "--root", "hw_isr_encoder_alpha", "--root", "hw_isr_encoder_beta"],
    "primary": ["primary"],
}


class _FakeSconsEnv:
    def __init__(self, project, pioenv="cell"):
        # PlatformIO's python, without site-packages: only the fake project's `tools` is seen
        wrapper = Path(project) / "python-nosite"
        wrapper.write_text(f'#!/bin/sh\nexec {__import__("sys").executable} -S "$@"\n')
        wrapper.chmod(0o755)
        self.vars = {"$PROJECT_DIR": str(project), "$PYTHONEXE": str(wrapper), "$PIOENV": pioenv}
        self.actions = []

    def subst(self, s):
        return self.vars[s]

    def AddPostAction(self, target, fn):
        self.actions.append((target, fn))


def _load_hook(project, pioenv="cell"):
    env = _FakeSconsEnv(project, pioenv)
    code = (ROOT / "metacell_tools" / "flash" / "pio_fwcheck.py").read_text()
    exec(compile(code, "pio_fwcheck.py", "exec"), {"Import": lambda name: None, "env": env})
    ((target, fn),) = env.actions
    assert target == "$BUILD_DIR/${PROGNAME}.elf"
    return env, fn


@pytest.mark.parametrize("pioenv", ["cell", "primary"])
@pytest.mark.parametrize(
    "checker, expect_rc, text",
    [
        (None, 0, "NOT run"),  # no checker: warn, build goes on
        ("lint_ok", 0, "lint ok"),
        ("lint_fails", 3, "FAILED"),  # checker says no: build fails
        ("no_lint", 0, "NOT run"),  # older checker without `lint`
    ],
)
def test_fwcheck_hook(tmp_path, capfd, monkeypatch, checker, expect_rc, text, pioenv):
    """The hook lints the cell image from the control path plus the glue's interrupt handlers, and the primary
    image from its own steady path (--role primary: it holds no control law, which used to fail every build)."""
    monkeypatch.delenv("MC_FWCHECK", raising=False)
    # a project whose own `tools` package (first on sys.path for `python -m`) shadows ours
    (tmp_path / "metacell_tools").mkdir()
    (tmp_path / "metacell_tools" / "__init__.py").write_text("")
    if checker:
        pkg = tmp_path / "metacell_tools" / "fwcheck"
        pkg.mkdir()
        (pkg / "__init__.py").write_text("")
        rc = 3 if checker == "lint_fails" else 0
        (pkg / "__main__.py").write_text(
            "import sys\n"
            "if '--help' in sys.argv:\n"
            f"    print({'lint report' if checker != 'no_lint' else 'report'!r}); sys.exit(0)\n"
            f"want = {WANT_ARGS[pioenv]!r}\n"
            "assert sys.argv[1:4] == ['lint', '--role', want[0]] and sys.argv[4] == '--elf', sys.argv\n"
            "assert sys.argv[6:] == want[1:], sys.argv\n"
            f"print('lint ok' if {rc} == 0 else 'lint bad'); sys.exit({rc})\n"
        )
    env, fn = _load_hook(tmp_path, pioenv)
    assert fn(None, [tmp_path / "firmware.elf"], env) == expect_rc
    assert text in capfd.readouterr().out
    monkeypatch.setenv("MC_FWCHECK", "skip")
    assert fn(None, [tmp_path / "firmware.elf"], env) == 0
