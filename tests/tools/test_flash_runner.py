"""Flashing tool, the run: boards behind a mocked PlatformIO uploader and mocked serial ports; every failure path of
a board after its upload, the summary and the exit status."""

from __future__ import annotations

import subprocess

import pytest

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash import inventory as inv
from metacell_tools.flash import runner as rn
from metacell_tools.flash.boards import XIAO_PID_APP, XIAO_PID_BOOT, XIAO_VID, Port
from metacell_tools.flash.plan import make_plan
from tests.tools.flash_fakes import FakeRig, fake_inventory, fake_ports, pio_tools, run_flash, write_ports_json


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
    assert bad[0].detail.startswith("bossac: no device (")  # the uploader's own words first
    assert any("FAILED: upload failed" in ln for ln in lines)
    assert "FAILED: cell 5 (0x14)" in rn.summary(outcomes)
    if stop:  # nothing after cell 5 was touched
        assert len(rig.runs) == 5 and set(rig.flashed) == {f"SN{i:02d}" for i in range(4)}
        assert [o.status for o in outcomes[5:]] == [rn.NOT_RUN] * 12
    else:  # every other board flashed and verified
        assert len(rig.runs) == 17 and len(bad) == 1 and "SN04" not in rig.flashed


@pytest.mark.parametrize("case", ["failed upload", "failed upload, stops", "skipped missing", "all ok"])
def test_flash_cli_exit_code(tmp_path, monkeypatch, capsys, case):
    """The exit status; --keep-going goes past a failed board, which otherwise stops the run (the rest untouched)."""
    pio_tools(tmp_path, monkeypatch, uploader="pio")  # PlatformIO's own uploader installed: it uploads
    n_ports = 16 if case == "skipped missing" else 17  # port 16 is the primary's
    failing = {"SN10"} if case.startswith("failed upload") else ()
    rig = FakeRig(fake_inventory(), fake_ports(n_ports), fail_upload=failing)
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
    extra = {"skipped missing": ["--skip-missing"], "failed upload": ["--keep-going"]}.get(case, [])
    rc = cli.main(args + extra)
    out = capsys.readouterr().out
    if case == "failed upload":
        assert rc == cli.EXIT_FAILED
        assert "16 of 17 board(s) flashed and verified; FAILED: cell 11 (0x1a)" in out
        assert len(rig.runs) == 17 and "NOT TRIED" not in out
    elif case == "failed upload, stops":
        assert rc == cli.EXIT_FAILED
        untried = ", ".join([f"cell {j} (0x{0x0F + j:02x})" for j in range(12, 17)] + ["primary"])
        assert (
            "10 of 17 board(s) flashed and verified; FAILED: cell 11 (0x1a); "
            f"NOT TRIED (stopped at the first failure; --keep-going goes on): {untried}\n"
        ) in out
        assert len(rig.runs) == 11 and len(rig.flashed) == 10  # nothing after cell 11 was touched
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
