"""A flashed firmware image as the image tier loads it: load segments, entry, symbols and cycle tables of the ELF."""

from __future__ import annotations

import hashlib
import io
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile
from elftools.elf.sections import SymbolTableSection

from metacell_common.target.board import FLASH, SRAM

from . import cycles

APP_BASE = 0x2000  # the UF2 bootloader's application start: the image's vector table
MAX_SEGMENTS = 16  # the project's images have two or three load segments
MAX_HEADERS, MAX_SECTIONS = 64, 1024  # an image has a few program headers and a few dozen sections
# the start-up code copies .data from flash to SRAM by words, and the vector table and literal pools are words
SEGMENT_ALIGN = 4


class ImageError(ValueError):
    """The file is not an image the tier can run (not a Cortex-M ELF linked at the application start)."""


@dataclass(frozen=True)
class Segment:
    addr: int  # load (physical) address in flash
    data: bytes


@dataclass
class FirmwareImage:
    path: Path
    segments: list[Segment]
    entry_sp: int
    entry_pc: int
    symbols: dict[str, tuple[int, int]]  # name -> (address, size): functions (Thumb bit cleared) and objects
    tables: cycles.BlockTables | None  # None: the board's decoder costs all its code (csrc/sam_cost.c)
    sha256: str
    heap_base: int  # end of static data in SRAM (the heap starts there); 0: unknown
    brk_var: int  # address of the heap's break pointer (sbrk's); 0: none, or unknown when heap_base is 0
    disassembly: cycles.Image = field(repr=False)

    def symbol(self, name: str) -> int:
        try:
            return self.symbols[name][0]
        except KeyError:
            raise ImageError(f"{self.path}: no symbol {name!r}") from None

    def size_of(self, name: str) -> int:
        return self.symbols[name][1]


@dataclass(frozen=True)
class LoadHeader:
    """A PT_LOAD program header as the ELF gives it."""

    paddr: int  # where its bytes are programmed (flash)
    vaddr: int  # where the program uses them (flash, or SRAM for .data and .bss)
    filesz: int
    memsz: int
    offset: int
    align: int


def _in(lo: int, n: int, region: tuple[int, int]) -> bool:
    """[lo, lo + n) inside region (start, end), written so no sum can pass the region's end unnoticed."""
    start, end = region
    return start <= lo <= end and n <= end - lo


def check_segments(path: Path, headers: list[LoadHeader], file_size: int) -> None:
    """ImageError (one line) unless every load segment is one the chip can hold: its bytes inside the file, programmed
    word-aligned in the application's flash (from APP_BASE), used in flash or SRAM, and no two overlapping."""
    if len(headers) > MAX_SEGMENTS:
        raise ImageError(f"{path}: {len(headers)} load segments (at most {MAX_SEGMENTS})")
    app = (APP_BASE, FLASH[1])
    for h in headers:
        where = f"{path}: load segment at 0x{h.paddr:x} (+0x{h.filesz:x})"
        if h.align > 1 and (h.align & (h.align - 1) or (h.vaddr - h.offset) % h.align):
            raise ImageError(
                f"{where}: alignment 0x{h.align:x}: not a power of two, or its address and file offset differ modulo it"
            )
        if not _in(h.offset, h.filesz, (0, file_size)):
            raise ImageError(f"{where}: its bytes at file offset 0x{h.offset:x} pass the file's end (0x{file_size:x})")
        if h.memsz < h.filesz:
            raise ImageError(f"{where}: memory size 0x{h.memsz:x} below its file size")
        if h.filesz and not _in(h.paddr, h.filesz, app):
            raise ImageError(f"{where}: outside the application flash 0x{app[0]:x}..0x{app[1]:x}")
        if h.filesz and h.paddr % SEGMENT_ALIGN:
            raise ImageError(f"{where}: not {SEGMENT_ALIGN}-byte aligned")
        if not (_in(h.vaddr, h.memsz, FLASH) or _in(h.vaddr, h.memsz, SRAM)):
            raise ImageError(f"{where}: used at 0x{h.vaddr:x} (+0x{h.memsz:x}), outside the chip's flash and SRAM")
    for what, spans in (
        ("programmed", sorted((h.paddr, h.filesz) for h in headers if h.filesz)),
        ("used", sorted((h.vaddr, h.memsz) for h in headers if h.memsz)),
    ):
        for (a, n), (b, _) in zip(spans, spans[1:]):
            if b < a + n:
                raise ImageError(f"{path}: load segments {what} at 0x{a:x} (+0x{n:x}) and 0x{b:x} overlap")


def load_image(path: str | Path) -> FirmwareImage:
    """The image of an ELF file (ImageError, one line, for anything the tier cannot run or that is not an ELF)."""
    path = Path(path)
    data = path.read_bytes()
    segs, syms, marks = read_elf(path, data)
    vt = next((sg for sg in segs if sg.addr == APP_BASE), None)
    if vt is None or len(vt.data) < 8:
        raise ImageError(f"{path}: no vector table at 0x{APP_BASE:x} (not linked for the bootloader)")
    sp, pc = struct.unpack_from("<II", vt.data, 0)
    image = cycles.parse_disassembly(cycles.disassemble(path))
    heap_base, brk_var = heap_layout(syms, marks)
    return FirmwareImage(
        path,
        segs,
        sp,
        pc,
        syms,
        cycles.block_tables(image),
        hashlib.sha256(data).hexdigest(),
        heap_base,
        brk_var,
        image,
    )


# the end of static data as GNU ld scripts for Cortex-M name it
HEAP_BASE_NAMES = ("__end__", "end", "_end", "__bss_end__")
# sbrk's static break pointer: newlib's heap_end (C, numbered by GCC), the Arduino SAMD core's _sbrk (C++)
BRK_PATTERN = re.compile(r"^(_ZZ5_sbrkE8heap_end|heap_end(\.\d+)?)$")


def read_elf(path: Path, data: bytes) -> tuple[list[Segment], dict[str, tuple[int, int]], dict[str, int]]:
    """(load segments, symbols, linker-script marks) of the ELF file `path` whose bytes are `data`, the segments
    checked (check_segments); ImageError (one line) for anything else. fuzz/fuzz_elf.py fuzzes it."""
    try:
        return _read_elf(path, data)
    except ImageError:
        raise
    except (ELFError, ValueError, LookupError, TypeError, AttributeError, AssertionError, struct.error) as e:
        # pyelftools on a malformed file: its own errors, or whatever its structures raise on nonsense values
        raise ImageError(f"{path}: not a readable ELF ({type(e).__name__}: {e})".replace("\n", " ")) from None
    except RecursionError:
        raise ImageError(f"{path}: not a readable ELF (nested too deeply)") from None


def _read_elf(path: Path, data: bytes) -> tuple[list[Segment], dict[str, tuple[int, int]], dict[str, int]]:
    with io.BytesIO(data) as fh:
        elf = ELFFile(fh)
        if elf["e_machine"] != "EM_ARM" or elf.elfclass != 32:
            raise ImageError(f"{path}: not a 32-bit ARM ELF")
        # the header's tables inside the file and of sizes an image has (pyelftools would walk 65535 entries)
        for what, off, num, size, most, want in (
            ("program header", elf["e_phoff"], elf["e_phnum"], elf["e_phentsize"], MAX_HEADERS, 32),
            ("section header", elf["e_shoff"], elf["e_shnum"], elf["e_shentsize"], MAX_SECTIONS, 40),
        ):
            if num and (num > most or size != want or not _in(off, num * size, (0, len(data)))):
                raise ImageError(
                    f"{path}: {what} table of {num} entries of {size} bytes at offset 0x{off:x}: not one an image has"
                )
        headers = [
            LoadHeader(
                int(seg["p_paddr"]),
                int(seg["p_vaddr"]),
                int(seg["p_filesz"]),
                int(seg["p_memsz"]),
                int(seg["p_offset"]),
                int(seg["p_align"]),
            )
            for seg in elf.iter_segments()
            if seg["p_type"] == "PT_LOAD"
        ]
        check_segments(path, headers, len(data))
        segs = [Segment(h.paddr, data[h.offset : h.offset + h.filesz]) for h in headers if h.filesz]
        symtab = elf.get_section_by_name(".symtab")
        if not isinstance(symtab, SymbolTableSection):
            raise ImageError(f"{path}: no symbol table")
        syms: dict[str, tuple[int, int]] = {}
        marks: dict[str, int] = {}  # linker-script symbols (no type)
        for s in symtab.iter_symbols():
            kind = s["st_info"]["type"]
            if kind in ("STT_FUNC", "STT_OBJECT") and s.name:
                addr = int(s["st_value"]) & (~1 if kind == "STT_FUNC" else ~0)
                syms.setdefault(s.name, (addr, int(s["st_size"])))
            elif kind == "STT_NOTYPE" and s.name:
                marks.setdefault(s.name, int(s["st_value"]))
    return segs, syms, marks


def heap_layout(syms: dict[str, tuple[int, int]], marks: dict[str, int]) -> tuple[int, int]:
    """(heap base, break pointer address) for the fast-forward's RAM compare: where static data ends and the
    variable holding the heap's top. An image that can grow a heap (it links _sbrk) but whose break pointer is not
    found gets (0, 0): the whole SRAM is compared."""
    base = next((marks[n] for n in HEAP_BASE_NAMES if n in marks), 0)
    brk = next((a for n, (a, size) in syms.items() if BRK_PATTERN.match(n) and size == 4), 0)
    if not brk and ("_sbrk" in syms or "_sbrk_r" in syms):
        return 0, 0
    return base, brk
