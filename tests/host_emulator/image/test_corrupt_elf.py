"""A corrupted cached ELF is refused before it reaches C: load segments the chip cannot hold (elfimage.check_segments),
a cache file that is not what was built (its recorded SHA-256), and the C loader's own bounds, which no address wraps.
Each refusal is one line and exit 2 from every command that loads the images (issue 32, item 1)."""

from __future__ import annotations

import base64
import dataclasses
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from host_emulator.image import build, elfimage, world
from host_emulator.image.elfimage import ImageError, Segment
from host_emulator.image.world import World, WorldError
from host_emulator.params import Params
from metacell_common import firmware

ROOT = Path(__file__).resolve().parents[3]
PT_LOAD = 1


def set_load(path: Path, k: int, **values: int) -> None:
    """Rewrite fields of the k-th PT_LOAD program header of an ELF32 little-endian file in place."""
    b = bytearray(path.read_bytes())
    (phoff,) = struct.unpack_from("<I", b, 28)
    phentsize, phnum = struct.unpack_from("<HH", b, 42)
    names = ("type", "offset", "vaddr", "paddr", "filesz", "memsz", "flags", "align")
    loads = [phoff + i * phentsize for i in range(phnum) if struct.unpack_from("<I", b, phoff + i * phentsize)[0] == 1]
    for name, v in values.items():
        struct.pack_into("<I", b, loads[k] + 4 * names.index(name), v & 0xFFFFFFFF)
    path.write_bytes(bytes(b))


@pytest.fixture
def elf(images, tmp_path) -> Path:
    """A copy of cell 3's cached ELF (two load segments: the code at 0x2000, .data programmed after it)."""
    p = tmp_path / "firmware.elf"
    shutil.copy2(images.cells[2], p)
    return p


def test_the_built_images_pass_the_segment_checks(images):
    for path in [*images.cells, images.primary]:
        img = elfimage.load_image(path)
        assert img.segments[0].addr == elfimage.APP_BASE and len(img.segments) == 2


@pytest.mark.parametrize(
    "k, change, says",
    [
        (1, {"paddr": 0xFFFFFF80}, "outside the application flash"),  # the issue's: addr + len wraps in uint32
        (1, {"paddr": 0x3FF80}, "outside the application flash"),  # ends 0x80 past the flash
        (1, {"paddr": 0x1000}, "outside the application flash"),  # over the bootloader
        (1, {"paddr": 0x7486}, "not 4-byte aligned"),
        (1, {"paddr": 0x2100}, "overlap"),  # programmed over the code
        (1, {"vaddr": 0x20007F00, "offset": 0x6F00}, "outside the chip's flash and SRAM"),  # .bss past the SRAM
        (1, {"memsz": 0x80}, "memory size 0x80 below its file size"),
        (1, {"offset": 0x7FFFF000}, "pass the file's end"),
        (0, {"filesz": 0xFFFFFFF0}, "pass the file's end"),
        (1, {"align": 0x1001}, "alignment 0x1001: not a power of two"),
        (1, {"offset": 0x7004}, "address and file offset differ modulo it"),
    ],
)
def test_load_segments_the_chip_cannot_hold_are_refused(elf, k, change, says):
    set_load(elf, k, **change)
    with pytest.raises(ImageError) as e:
        elfimage.load_image(elf)
    msg = str(e.value)
    assert says in msg and str(elf) in msg and "\n" not in msg


# fuzz/fuzz_elf.py's first find: e_phnum = 60416 entries of 0 bytes, which pyelftools walked for minutes
PHNUM_60416 = base64.b64decode(
    "f0VMRgEBAQAAAAAAAAAAAAIAKAABAAAAAQEBAAAAAAAAAH9FTEYBAQAAAAAA7AEAAAACAAADAAAAAAAAAgAFNAAgAAJGAQEBAAAAAAAAAAAAAgAoAAEAAAAB"
    "AQEAAAAAAAAAAAAAAgAFNAAgAAIAKAAIAAcAACgACAAAAAAAAAAABwA="
)


@pytest.mark.parametrize(
    "blob",
    [b"", b"\x7fELF", b"\x7fELF\x01\x01\x01" + bytes(9) + b"\x02\x00\x28\x00" + bytes(200), PHNUM_60416],
    ids=["empty", "magic", "no-tables", "phnum-60416"],
)
def test_what_is_not_a_readable_elf_is_one_image_error_line(tmp_path, blob):
    p = tmp_path / "firmware.elf"
    p.write_bytes(blob)
    with pytest.raises(ImageError) as e:
        elfimage.load_image(p)
    assert "\n" not in str(e.value)


def test_header_tables_outside_the_file_are_refused(elf):
    data = bytearray(elf.read_bytes())
    struct.pack_into("<I", data, 32, len(data) - 100)  # e_shoff: the section headers run past the end
    elf.write_bytes(bytes(data))
    with pytest.raises(ImageError, match="section header table of .* entries of 40 bytes"):
        elfimage.load_image(elf)


def test_the_c_loader_refuses_a_segment_whose_end_wraps(images, monkeypatch):
    """The C check itself (Python's bypassed): `addr + len > SAM_FLASH_SIZE` wrapped for 0xFFFFFF80 + 0x100 and
    memcpy wrote 4 GiB away (exit 139); written as `len > SIZE - addr` it refuses the segment."""
    load = world.load_image

    def wrapping(path):
        img = load(path)
        return dataclasses.replace(img, segments=[*img.segments, Segment(0xFFFFFF80, bytes(0x100))])

    monkeypatch.setattr(world, "load_image", wrapping)
    with pytest.raises(WorldError, match=r"image segment at 0xffffff80 \(\+256\) outside the application flash"):
        World(Params(cells=1), images)


# ---------------------------------------------------------------- the commands, on a copy of the cache


@pytest.fixture
def cache_copy(images, tmp_path) -> tuple[dict, Path]:
    """(environment, the copy's digest folder): MC_BUILD_DIR names a build folder whose image-elf/ is a copy of the
    cache (records included) and whose compiled modules are the real ones (symlinks: nothing rebuilds)."""
    real = firmware.BUILD_DIR
    top = tmp_path / "build"
    top.mkdir()
    for name, src in (("host", real), ("image", real.parent / "image")):
        src.mkdir(parents=True, exist_ok=True)
        (top / name).symlink_to(src)
    digest = images.cells[0].parents[1]
    dst = top / "image-elf" / digest.name
    for elf in [*images.cells, images.primary]:
        (dst / elf.parent.name).mkdir(parents=True)
        for f in (elf, build.digest_record(elf)):
            shutil.copy2(f, dst / elf.parent.name / f.name)
    env = dict(os.environ, MC_BUILD_DIR=str(top / "host"))
    return env, dst


COMMANDS = [
    ["run", "default", "--set", "model=image", "--quiet", "--out", "OUT"],
    ["image", "registers", "--board", "cell3"],
    ["serve", "--set", "model=image", "--duration", "1"],
]


def run_cli(env: dict, argv: list[str], out: Path) -> subprocess.CompletedProcess:
    argv = [str(out) if a == "OUT" else a for a in argv]
    return subprocess.run(
        [sys.executable, "-m", "host_emulator", *argv], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
@pytest.mark.parametrize("argv", COMMANDS, ids=["run", "image-registers", "serve"])
def test_a_cached_elf_with_a_wrapping_segment_is_one_line_exit_2(cache_copy, tmp_path, argv):
    env, digest = cache_copy
    elf = digest / "cell03" / "firmware.elf"
    set_load(elf, 1, paddr=0xFFFFFF80)
    build.record_digest(elf)  # a consistent cache: the segment check is what refuses it
    out = tmp_path / "out"
    r = run_cli(env, argv, out)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(elf) in lines[0] and "outside the application flash" in lines[0], r.stderr
    assert not out.exists() or not any(out.iterdir())  # run makes --out before it simulates: nothing in it


@pytest.mark.slow
def test_a_cached_elf_that_differs_from_its_record_is_one_line_exit_2(cache_copy, tmp_path):
    env, digest = cache_copy
    elf = digest / "cell03" / "firmware.elf"
    set_load(elf, 1, paddr=0xFFFFFF80)  # changed after it was recorded
    out = tmp_path / "out"
    r = run_cli(env, COMMANDS[0], out)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(elf) in lines[0] and "SHA-256" in lines[0] and "corrupted" in lines[0], r.stderr
    assert not out.exists() or not any(out.iterdir())  # run makes --out before it simulates: nothing in it


def test_the_cache_checks_each_elf_against_its_record(cache_copy, monkeypatch):
    _, digest = cache_copy
    monkeypatch.setattr(build, "cache_dir", lambda: digest.parent)
    monkeypatch.setattr(build, "inputs_digest", lambda root=build.ROOT: digest.name)
    assert build.build_images(3, primary=False).cells[2] == digest / "cell03" / "firmware.elf"
    rec = build.digest_record(digest / "cell02" / "firmware.elf")
    rec.unlink()  # a cache from before the records: recorded at first use
    build.build_images(3, primary=False)
    assert rec.read_text().split()[0] == build.sha256_file(digest / "cell02" / "firmware.elf")
    elf = digest / "cell03" / "firmware.elf"
    data = elf.read_bytes()
    elf.write_bytes(data[:-1] + bytes([data[-1] ^ 1]))  # one bit of the last byte
    with pytest.raises(build.CorruptCacheError, match="cell03/firmware.elf: SHA-256"):
        build.build_images(3, primary=False)
    build.build_images(2, primary=False)  # the cells it does not load are not read
