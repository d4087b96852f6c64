"""The register table is checked before it reaches C (regtable.check): interrupt lines, widths, offsets, fields and
instance windows the chip and the runtime can hold. A corrupted vendor header is refused, not replaced by the
committed snapshot, and not compiled into a runtime that shifts by 40 (issue 32, item 10)."""

from __future__ import annotations

import copy
import dataclasses
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from host_emulator.image import regsnapshot, regtable
from host_emulator.image.regtable import Field, RegTableError

from .vendor import include_dirs

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture
def tree(tmp_path) -> Path:
    """A PlatformIO tree holding a copy of the vendor headers (edited by the tests)."""
    atmel, core = include_dirs()
    t = tmp_path / "tree"
    shutil.copytree(atmel, t / "packages" / regtable.CMSIS_ATMEL_SUBDIR)
    shutil.copytree(core, t / "packages" / regtable.CMSIS_CORE_SUBDIR)
    return t


def edit_device_header(tree: Path, old: str, new: str) -> None:
    h = tree / "packages" / regtable.CMSIS_ATMEL_SUBDIR / regtable.DEVICE_HEADER
    text = h.read_text()
    assert text.count(old) == 1, f"{old!r} not once in the device header: the edit's target moved"
    h.write_text(text.replace(old, new))


TC3_IRQ = "TC3_IRQn                 = 18,"


def test_an_interrupt_line_beyond_the_nvic_in_the_vendor_header_is_refused(tree):
    edit_device_header(tree, TC3_IRQ, "TC3_IRQn                 = 40,")
    with pytest.raises(RegTableError) as e:
        regtable.load(str(tree))
    msg = str(e.value)
    assert "TC3_IRQn = 40" in msg and "0..31" in msg and "\n" not in msg
    with pytest.raises(RegTableError, match="TC3_IRQn = 40"):  # the snapshot stands in for missing headers only
        regsnapshot.load_or_snapshot(str(tree))


def test_an_interrupt_line_given_twice_is_refused(tree):
    edit_device_header(tree, TC3_IRQ, "TC3_IRQn                 = 19,")  # TC4's
    with pytest.raises(RegTableError, match="TC3_IRQn = 19: the line of TC4 already|TC4_IRQn = 19: the line of TC3"):
        regtable.load(str(tree))


def test_the_unedited_copy_gives_the_committed_table(tree):
    assert regsnapshot.snapshot_text(regtable.load(str(tree)), []) == regsnapshot.snapshot_text(
        regsnapshot.load_snapshot(), []
    )


@pytest.mark.slow
def test_a_run_against_the_corrupted_header_is_refused_in_one_line(images, tree, tmp_path):
    edit_device_header(tree, TC3_IRQ, "TC3_IRQn                 = 40,")
    out = tmp_path / "out"
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "run", "default", "--set", "model=image", "--set", "t_end_s=0.05"]
        + ["--quiet", "--out", str(out)],
        cwd=ROOT,
        env=dict(os.environ, MC_PIO_TREE=str(tree)),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "TC3_IRQn = 40" in lines[0], r.stderr


# ---------------------------------------------------------------- check() on edited copies of the table


def edited(change) -> regtable.Table:
    t = copy.deepcopy(regsnapshot.load_snapshot())
    change(t)
    return t


def _reg(t, periph, name):
    p = t.periph(periph)
    i = next(k for k, r in enumerate(p.registers) if r.name == name)
    return p, i


def _set_reg(t, periph, name, **kw):
    p, i = _reg(t, periph, name)
    p.registers[i] = dataclasses.replace(p.registers[i], **kw)


CASES = [
    (lambda t: setattr(t.periph("TC3"), "irq", 40), "TC3_IRQn = 40"),
    (lambda t: setattr(t.periph("TC3"), "irq", -2), "TC3_IRQn = -2"),
    (lambda t: setattr(t.periph("TC3"), "base", 0x50000000), "TC3 at 0x50000000"),
    (lambda t: setattr(t.periph("PM"), "size", 0x2000), "outside the chip's peripheral regions"),
    (lambda t: setattr(t.periph("TC4"), "base", 0x42002C10), "overlap"),
    (lambda t: setattr(t.periph("TC3"), "views", ("A", "B", "C", "D", "E")), "5 mode views"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", size=3), "3 bytes wide"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", offset=0x1F), "outside TC3's 0x20-byte window"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", offset=0x1), "not aligned"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", reset=0x10000), "reset value 0x10000"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", access="X"), "access 'X'"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", fields=(Field("BAD", 14, 4),)), "field BAD at bit 14, 4 wide"),
    (lambda t: _set_reg(t, "TC3", "COUNT16.CTRLA", fields=(Field("BAD", 3, 0),)), "field BAD at bit 3, 0 wide"),
    (lambda t: t.pinmux.append(regtable.PinFunction(64, 0, "X", "Y")), "pin 64"),
    (lambda t: setattr(t.periph("PORT"), "pac", 66), "ID_PORT = 66: PORT at 0x41004400 is not on APB bridge 2"),
    (lambda t: setattr(t.periph("TC4"), "pac", 75), "ID_TC4 = 75: the PAC bit of TC3 already"),
    (lambda t: setattr(t.periph("PORT"), "pac", None), "no ID_PORT (its PAC bit)"),
    (lambda t: setattr(t.periph("PORT"), "pac", 32), "ID_PORT = 32: bit 0 of a bridge is its PAC"),
    (lambda t: t.peripherals.extend(copy.deepcopy(t.peripherals[:12])), "instances (1..48)"),
]


@pytest.mark.parametrize("change, says", CASES)
def test_values_the_chip_or_the_runtime_cannot_hold_are_refused(change, says):
    t = edited(change)
    with pytest.raises(RegTableError) as e:
        regtable.check(t)
    assert says in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(RegTableError):  # nothing unchecked is emitted for the compiler
        regtable.emit_c(t)


def test_the_committed_table_passes():
    regtable.check(regsnapshot.load_snapshot())


def test_the_regions_are_those_the_runtime_maps():
    text = (ROOT / "host_emulator" / "image" / "csrc" / "sam_mmio.c").read_text()

    def array(name):
        m = re.search(rf"{name}\[NREGIONS\]\s*=\s*\{{([^}}]*)\}}", text)
        assert m, name
        return [int(v.strip().rstrip("u"), 16) for v in m.group(1).split(",")]

    assert list(zip(array("REGION_BASE"), array("REGION_SIZE"))) == list(regtable.PERIPHERAL_REGIONS)
    sam_h = (ROOT / "host_emulator" / "image" / "csrc" / "sam.h").read_text()
    assert re.search(rf"#define SAM_MAX_PERIPH {regtable.MAX_PERIPHERALS}\b", sam_h)
