"""Checks that only mean something under the sanitizers: run by test_sanitizers.py in a Python with the ASan runtime
preloaded and MC_SANITIZE=1 (not collected by the suite itself: the file name has no test_ prefix).

The boards run their firmware, and the C API and the USB descriptor parser get out-of-range requests: any read or
write outside an object, or undefined behaviour, ends the run with the sanitizer's report."""

from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest
from elftools.elf.dynamic import DynamicSection
from elftools.elf.elffile import ELFFile

from host_emulator.image import runtime
from host_emulator.image.world import World
from host_emulator.params import Params
from tests.host_emulator.image.conftest import configured, images_or_skip

RAM_BASE, RAM_SIZE, FLASH_SIZE = 0x2000_0000, 0x8000, 0x40000


@pytest.fixture(scope="module")
def images():
    return images_or_skip(2)


def needed(so: Path) -> list[str]:
    with open(so, "rb") as fh:
        dyn = ELFFile(fh).get_section_by_name(".dynamic")
        assert isinstance(dyn, DynamicSection)
        return [t.needed for t in dyn.iter_tags() if t.entry.d_tag == "DT_NEEDED"]


def test_the_runtime_under_test_is_the_sanitized_build():
    runtime.load()
    maps = Path("/proc/self/maps").read_text().split()
    modules = {Path(p) for p in maps if "/_mcimg_" in p and p.endswith(".so")}
    assert modules, "no image runtime loaded"
    for so in modules:
        assert any(n.startswith("libasan") for n in needed(so)), f"{so} is not built with ASan"
        assert any(n.startswith("libubsan") for n in needed(so)), f"{so} is not built with UBSan"
    assert any("libasan" in p for p in maps), "the ASan runtime is not preloaded"
    assert sys.modules["metacell_common.firmware"].SANITIZE


def test_two_cells_and_the_primary_run_their_firmware(images):
    """Boot, USB enumeration, I2C configuration of every cell, then 50 ms of control with the plant: the CPU hooks,
    the MMIO layer and most peripheral models, the plant's stepper and the firmware library in the loop."""
    w, lap = configured(images, 2)
    lap.pump(0.05)
    for b in w.boards:
        info = w.info(b.index)
        assert info.hardfaults == 0 and not info.lockup, (b.name, w.notes()[-5:])


def test_out_of_range_requests_to_the_c_api_are_refused(images):
    w = World(Params(cells=1), images)
    ffi, lib, h = w.ffi, w.lib, w._w
    buf = ffi.new("uint8_t[]", 0x40)
    for addr, n in [
        (0xFFFFFFF0, 0x20),
        (RAM_BASE + RAM_SIZE - 0x10, 0x20),
        (FLASH_SIZE - 0x10, 0x20),
        (RAM_BASE - 8, 0x10),
    ]:
        assert lib.sam_world_read_mem(h, 0, addr, buf, n) == -1, hex(addr)
    assert lib.sam_world_read_mem(h, 0, RAM_BASE + RAM_SIZE - 0x20, buf, 0x20) == 0
    assert lib.sam_world_read_mem(h, 0, FLASH_SIZE - 0x20, buf, 0x20) == 0
    row = ffi.new("uint8_t[]", 300)
    assert lib.sam_world_set_user_row(h, 0, row, 300) == -1
    data = ffi.new("uint8_t[]", 0x200)
    assert lib.sam_harness_flash(h, 0, 0xFFFFFF00, data, 0x200) == -1
    assert lib.sam_harness_flash(h, 0, FLASH_SIZE - 0x100, data, 0x200) == -1
    assert lib.sam_world_reg_value(h, 0, 1 << 20, ffi.new("uint32_t *")) == -1


def test_the_usb_configuration_parser_reads_only_what_it_is_given(images):
    """Random and truncated descriptors, each in a buffer of exactly its size (ASan's red zone right after it)."""
    ffi, lib = runtime.load()
    rng = random.Random(32)
    out = [ffi.new("int32_t *") for _ in range(3)]
    good = bytes.fromhex(
        "09022000020100c032 0904000001020201 00 0705810340000a 0904010002 0a0000 00 0705020240 0000 0705830240 0000"
    )
    for n in range(len(good) + 1):
        d = ffi.new("uint8_t[]", good[:n]) if n else ffi.NULL
        lib.sam_usb_parse_config(d, n, *out)
    for _ in range(2000):
        n = rng.randrange(1, 80)
        blob = bytes(rng.randrange(256) if rng.random() < 0.7 else rng.choice((2, 4, 5, 7, 9)) for _ in range(n))
        lib.sam_usb_parse_config(ffi.new("uint8_t[]", blob), n, *out)
