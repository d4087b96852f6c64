"""Flashing tool, the plan: port listings, the inventory, the plan and its commands, the build flags against the
firmware's own checks and PlatformIO's configuration, the post-build hook."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import inventory as inv
from metacell_tools.flash.addresses import cell_address
from metacell_tools.flash.boards import (
    XIAO_PID_APP,
    XIAO_PID_BOOT,
    XIAO_VID,
    Port,
    PortListError,
    ports_from_json,
    xiao_ports,
)
from metacell_tools.flash.plan import PlanError, describe, make_plan, parse_only
from tests.tools.flash_fakes import fake_inventory, fake_ports, pio_tools, write_ports_json

ROOT = Path(__file__).resolve().parents[2]


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

    pio_tools(tmp_path, monkeypatch, uploader="pio")  # PlatformIO's own uploader installed: it uploads
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
    sheet = make_plan(fake_inventory(64), fake_ports(65), cells=64)  # a sheet's last cell builds too
    for step in sheet.steps[16:64:47]:  # cells 17 and 64
        flags = dict(step.env_vars)["PLATFORMIO_BUILD_SRC_FLAGS"].split()
        assert _cell_config(flags).returncode == 0, flags
    for bad, why in (
        (["-DMC_CELL_INDEX=65", "-DMC_CELL_ADDR=0x50"], "MC_CELL_INDEX must be"),
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
