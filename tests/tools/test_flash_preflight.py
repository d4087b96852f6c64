"""Flashing tool, before the first board: what this machine builds and uploads with, what is missing (one line, exit
2), the offset guard, and the commands the plan shows for each uploader."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import inventory as inv
from metacell_tools.flash.boards import XIAO_PID_BOOT, Port
from metacell_tools.flash.bossac import BossacUpload
from metacell_tools.flash.plan import make_plan, with_toolchain
from metacell_tools.flash.toolchain import APP_OFFSET, PreflightError, check_offset, find_toolchain
from tests.tools.flash_fakes import (
    STANDIN_PIO,
    calls,
    core_dir,
    fake_inventory,
    fake_ports,
    pio_tools,
    write_exe,
    write_ports_json,
)

ROOT = Path(__file__).resolve().parents[2]


def offline_tree(path: Path, tool_bossac: bool = False) -> Path:
    """A stand-in offline tree: its use.sh runs `$PIO ARGS` in the project (as the real one does, minus the links)."""
    core_dir(path, tool_bossac=tool_bossac)
    (path / "use.sh").write_text('#!/usr/bin/env bash\nset -e\nshift\ncd "$1"\nshift\nexec "$PIO" "$@"\n')
    return path


@pytest.mark.parametrize(
    "machine, uploader, want",
    [
        ("pio + tool-bossac", "auto", "pio"),
        ("pio + tool-bossac + bossac", "auto", "pio"),  # PlatformIO's own uploader first, when it is installed
        ("pio + tool-bossac + bossac", "bossac", "bossac"),
        ("pio + bossac", "auto", "bossac"),
        ("tree + bossac", "auto", "bossac"),
        ("tree with tool-bossac", "auto", "pio"),
    ],
)
def test_the_uploader_is_platformios_when_installed_else_bossac(tmp_path, monkeypatch, machine, uploader, want):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="pio" if "pio + tool-bossac" in machine else "bossac")
    if "bossac" in machine.replace("tool-bossac", ""):
        write_exe(bin_dir / "bossac", "")
    else:
        (bin_dir / "bossac").unlink(missing_ok=True)
    if machine.startswith("tree"):
        tree = offline_tree(tmp_path / "tree", tool_bossac="tool-bossac" in machine)
        monkeypatch.setenv("MC_PIO_TREE", str(tree))
        monkeypatch.setenv("PLATFORMIO_CORE_DIR", str(tmp_path / "empty"))
    tools = find_toolchain("pio", ROOT, uploader=uploader)
    assert tools.uploader == want
    assert tools.bossac == (str(bin_dir / "bossac") if want == "bossac" else None)
    if machine.startswith("tree"):  # the tree's use.sh runs the PlatformIO named here, its work dir kept
        assert tools.build_prefix == ("bash", str(tree / "use.sh"), str(tree.resolve()), str(ROOT))
        assert dict(tools.build_env) == {"PIO": str(bin_dir / "pio"), "PIO_OFFLINE_WORK": str(ROOT / ".pio/offline")}
        assert "through MC_PIO_TREE's use.sh" in tools.describe()
    else:
        assert tools.build_prefix == ("pio",) and tools.build_env == ()


@pytest.mark.parametrize(
    "machine, args, missing",
    [
        ("nothing", {}, ["flash cannot build the firmware images: no offline PlatformIO tree (set MC_PIO_TREE)",
                         "cannot upload: neither PlatformIO's uploader (tool-bossac, not in", "apt-get install bossa"]),
        ("tree", {}, ["cannot upload: neither PlatformIO's uploader (tool-bossac, not in MC_PIO_TREE's",
                      "nor bossac (bossac, not found)", "apt-get install bossa-cli"]),
        ("tree", {"uploader": "pio"}, ["PlatformIO's uploader (tool-bossac ~1.10700.0) is not in",
                                       "pio pkg install -g -t platformio/tool-bossac@~1.10700.0"]),
        ("tree", {"uploader": "bossac"}, ["cannot upload: bossac not found (install Debian's bossac"]),
        ("tree", {"bossac": "/nowhere/bossac"}, ["nor bossac (/nowhere/bossac, not found)"]),
        ("tree", {"pio": "nope"}, ["cannot build: PlatformIO (nope) not found (pip install platformio==6.2.0"]),
        ("bad tree", {}, ["cannot build: MC_PIO_TREE=", "is not an offline PlatformIO tree (no use.sh)"]),
        ("pio + tool-bossac", {"offset": 0x4000}, ["--offset applies to bossac uploads only"]),
    ],
)  # fmt: skip
def test_preflight_names_everything_missing_in_one_line(tmp_path, monkeypatch, machine, args, missing):
    pio_tools(tmp_path, monkeypatch, uploader="pio" if machine == "pio + tool-bossac" else "none")
    if "tree" in machine:
        tree = tmp_path / "tree"
        if machine == "tree":
            offline_tree(tree)
        else:
            tree.mkdir()
        monkeypatch.setenv("MC_PIO_TREE", str(tree))
    with pytest.raises(PreflightError) as got:
        find_toolchain(args.pop("pio", "pio"), ROOT, **args)
    msg = str(got.value)
    assert "\n" not in msg
    for text in missing:
        assert text in msg


@pytest.mark.parametrize(
    "offset, force, why",
    [
        (0, False, "--offset 0x0 would overwrite the XIAO's bootloader (flash 0x0000-0x1FFF)"),
        (0x1F00, False, "--offset 0x1f00 would overwrite the XIAO's bootloader"),
        (0x2080, False, "--offset 0x2080: must be a multiple of 0x100"),
        (-0x100, True, "must be a multiple of 0x100 (a flash row) and not negative"),
        (0, True, ""),
        (APP_OFFSET, False, ""),
        (0x4000, False, ""),
    ],
)
def test_offset_guard(offset, force, why):
    got = check_offset(offset, force)
    assert (why in got and "\n" not in got) if why else got == ""


def test_an_upload_below_the_bootloader_is_refused_before_anything_else(tmp_path, monkeypatch, capsys):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    inv.save(tmp_path / "b.json", fake_inventory())
    ports = write_ports_json(tmp_path / "p.json", fake_ports(17))
    args = ["flash", "--inventory", str(tmp_path / "b.json"), "--ports-json", str(ports), "--log-dir", str(tmp_path)]
    for offset in ("0", "0x0", "0x1000"):
        assert cli.main(args + ["--offset", offset]) == cli.EXIT_USAGE
        cap = capsys.readouterr()
        assert cap.out == "" and cap.err.count("\n") == 1
        assert cap.err.startswith(f"error: --offset 0x{int(offset, 0):x} would overwrite the XIAO's bootloader")
    assert calls(bin_dir) == []  # nothing built, nothing uploaded
    assert cli.main(["plan", *args[1:5], "--offset", "0", "--overwrite-bootloader", "--only", "3"]) == cli.EXIT_OK
    assert "--offset=0x0 --erase" in capsys.readouterr().out  # forced: the plan says so


def test_flash_with_neither_uploader_says_so_in_one_line_before_touching_a_board(tmp_path):
    """Acceptance: no PlatformIO uploader, no bossac (PATH without it, an empty PlatformIO core dir): one line, exit 2,
    nothing run, no board touched."""
    bin_dir = tmp_path / "bin"
    write_exe(bin_dir / "pio", STANDIN_PIO)
    (tmp_path / "core").mkdir()
    inv.save(tmp_path / "b.json", fake_inventory())
    ports = write_ports_json(tmp_path / "p.json", fake_ports(17))
    env = {k: v for k, v in os.environ.items() if k not in ("MC_PIO_TREE", "MC_PIO", "MC_BOSSAC")}
    env.update(PATH=str(bin_dir), PLATFORMIO_CORE_DIR=str(tmp_path / "core"), PYTHONPATH=str(ROOT))
    for extra in ([], ["--keep-going", "--uploader", "bossac"]):
        r = subprocess.run(
            [sys.executable, "-m", "metacell_tools.flash", "flash", "--inventory", str(tmp_path / "b.json")]
            + ["--ports-json", str(ports), "--log-dir", str(tmp_path / "logs"), *extra],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert r.returncode == 2 and r.stdout == "", (r.stdout, r.stderr)
        assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: flash cannot build"), r.stderr
        assert "bossa-cli" in r.stderr and ("neither PlatformIO's uploader" in r.stderr) == (not extra)
    assert calls(bin_dir) == [] and not (tmp_path / "logs").exists()


def test_plan_shows_the_build_then_the_touch_and_bossac(tmp_path, monkeypatch, capsys):
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    inv.save(tmp_path / "b.json", fake_inventory())
    ports = fake_ports(17)
    ports[4] = Port(ports[4].device, ports[4].vid, XIAO_PID_BOOT, ports[4].serial_number)  # cell 5: in its bootloader
    rc = cli.main(
        ["plan", "--inventory", str(tmp_path / "b.json"), "--project", "/rig/proj", "--only", "4,5,primary"]
        + ["--ports-json", str(write_ports_json(tmp_path / "p.json", ports))]
    )
    assert rc == 0
    out = capsys.readouterr().out.splitlines()
    i = out.index("commands:")
    bossac = f"{bin_dir}/bossac --port=PORT --usb-port=1 --info --offset=0x2000 --erase --write --verify --reset"
    assert [ln.strip() for ln in out[i + 1 :]] == [
        "PLATFORMIO_BUILD_DIR=/rig/proj/.pio/build-cell04 "
        "PLATFORMIO_BUILD_SRC_FLAGS='-DMC_CELL_INDEX=4 -DMC_CELL_ADDR=0x13' "
        f"{bin_dir}/pio run -d /rig/proj -e cell",
        f"1200-baud touch of /dev/ttyACM3, then {bossac} /rig/proj/.pio/build-cell04/cell/firmware.bin"
        "   (PORT: serial SN03's bootloader port)",
        "PLATFORMIO_BUILD_DIR=/rig/proj/.pio/build-cell05 "
        "PLATFORMIO_BUILD_SRC_FLAGS='-DMC_CELL_INDEX=5 -DMC_CELL_ADDR=0x14' "
        f"{bin_dir}/pio run -d /rig/proj -e cell",
        f"{bossac} /rig/proj/.pio/build-cell05/cell/firmware.bin   (PORT: serial SN04's bootloader port)",
        f"PLATFORMIO_BUILD_DIR=/rig/proj/.pio/build-primary PLATFORMIO_BUILD_SRC_FLAGS='' {bin_dir}/pio run -d "
        "/rig/proj -e primary",
        f"1200-baud touch of /dev/ttyACM16, then {bossac} /rig/proj/.pio/build-primary/primary/firmware.bin"
        "   (PORT: serial SN16's bootloader port)",
        f"build: PlatformIO ({bin_dir}/pio); upload: bossac ({bin_dir}/bossac) at offset 0x2000, after a 1200-baud "
        "touch",
    ]
    assert calls(bin_dir) == []


def test_plan_through_the_offline_tree(tmp_path, monkeypatch):
    """MC_PIO_TREE set: the build runs through its use.sh (its PIO, a kept work dir), with either uploader."""
    bin_dir = pio_tools(tmp_path, monkeypatch, uploader="bossac")
    tree = offline_tree(tmp_path / "tree")
    monkeypatch.setenv("MC_PIO_TREE", str(tree))
    proj = tmp_path / "proj"
    proj.mkdir()
    plan = make_plan(fake_inventory(), fake_ports(17), project=proj, only={2})
    use = ("bash", str(tree / "use.sh"), str(tree.resolve()), str(proj), "run", "-e", "cell")
    (step,) = with_toolchain(plan, find_toolchain("pio", proj), proj).steps
    assert step.argv == use and step.upload == BossacUpload(str(bin_dir / "bossac"), step.upload.firmware)
    assert dict(step.env_vars)["PIO"] == str(bin_dir / "pio")
    assert step.upload.firmware == proj / ".pio" / "build-cell02" / "cell" / "firmware.bin"
    core_dir(tree, tool_bossac=True)  # the tree now has PlatformIO's uploader: it uploads
    (step,) = with_toolchain(plan, find_toolchain("pio", proj), proj).steps
    assert step.argv == (*use, "-t", "upload", "--upload-port", "/dev/ttyACM1") and step.upload is None
    # and the stand-in tree's use.sh really runs the build with the step's variables
    r = subprocess.run(
        step.argv[:4] + ("run", "-e", "cell"),
        env={**os.environ, **dict(step.env_vars), "PATH": f"{bin_dir}{os.pathsep}{os.defpath}"},
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert [c["argv"][1:] for c in calls(bin_dir)] == [["run", "-e", "cell"]]
    assert json.loads((bin_dir / "calls.jsonl").read_text())["PIO_OFFLINE_WORK"] == str(proj / ".pio/offline")
    assert (proj / ".pio" / "build-cell02" / "cell" / "firmware.bin").is_file()
