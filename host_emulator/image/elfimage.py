"""A flashed firmware image as the image tier loads it: load segments, entry, symbols and cycle tables of the ELF."""

from __future__ import annotations

import hashlib
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

from elftools.elf.elffile import ELFFile
from elftools.elf.sections import SymbolTableSection

from . import cycles

APP_BASE = 0x2000  # the UF2 bootloader's application start: the image's vector table


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


def load_image(path: str | Path) -> FirmwareImage:
    path = Path(path)
    data = path.read_bytes()
    with open(path, "rb") as fh:
        elf = ELFFile(fh)
        if elf["e_machine"] != "EM_ARM" or elf.elfclass != 32:
            raise ImageError(f"{path}: not a 32-bit ARM ELF")
        segs = []
        for seg in elf.iter_segments():
            if seg["p_type"] != "PT_LOAD" or seg["p_filesz"] == 0:
                continue
            segs.append(Segment(int(seg["p_paddr"]), seg.data()[: seg["p_filesz"]]))
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


def heap_layout(syms: dict[str, tuple[int, int]], marks: dict[str, int]) -> tuple[int, int]:
    """(heap base, break pointer address) for the fast-forward's RAM compare: where static data ends and the
    variable holding the heap's top. An image that can grow a heap (it links _sbrk) but whose break pointer is not
    found gets (0, 0): the whole SRAM is compared."""
    base = next((marks[n] for n in HEAP_BASE_NAMES if n in marks), 0)
    brk = next((a for n, (a, size) in syms.items() if BRK_PATTERN.match(n) and size == 4), 0)
    if not brk and ("_sbrk" in syms or "_sbrk_r" in syms):
        return 0, 0
    return base, brk
