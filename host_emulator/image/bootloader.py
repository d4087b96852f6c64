"""The XIAO's UF2 bootloader in the image tier: found through MC_BOOTLOADER, pinned by its hash, and its cycle costs.

The boards ship with Seeed's build of the UF2 bootloader (uf2-samdx1 v3.7.0-33-g90ff611, 8,192 bytes at flash
0x0000-0x1FFF). No package registry has it, so the tier finds the .bin through the environment variable
``MC_BOOTLOADER`` (its path) and runs only that exact file (its sha256 is pinned: the cycle costs below and what the
tests expect of it are per binary). With ``boot = "bootloader"`` (``WorldConfig.boot``, the scene key
``model_options.image.boot``) a board runs it from the reset vector and the bootloader starts the application at
0x2000 by itself; with ``boot = "direct"`` (the default) the tier starts the application directly, as before.

Cycle costs: the image tier charges every executed block from prefix-sum tables built from a disassembly
(``cycles.block_tables``). The bootloader has no ELF, so its tables come from a linear sweep of the .bin by
``arm-none-eabi-objdump``; a sweep decodes literal-pool data as instructions and may swallow the start of a real
instruction behind it (it does at 0xdc in this binary), so the sweep restarts two bytes on wherever it decoded a
32-bit encoding that is not an ARMv6-M instruction (only BL, MRS, MSR and the barriers are). ``boot_tables`` is
the one place where these tables are made: a cost model that decodes the flash itself can replace it.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

from metacell_common.target.cycles import Function

from . import cycles

ENV = "MC_BOOTLOADER"
FILE_NAME = "bootloader-XIAO_m0-v3.7.0-33-g90ff611-dirty.bin"
SHA256 = "f8753bd94e00907c5b25b4c76f608b1b8d20024af88ed1461b3d8606729c5fd3"
SIZE = 0x2000  # flash 0x0000-0x1FFF; the application starts at 0x2000
BOOT_MODES = ("direct", "bootloader")
BOOTPROT_ASSUMED = 7  # the boards' user row: nothing protected (the XIAOs' fuse is unknown; csrc/sam.h)


class BootloaderError(RuntimeError):
    """The bootloader cannot be had (MC_BOOTLOADER unset or not the pinned file); the message is one line."""


def unavailable() -> str:
    return (
        f"the bootloader is not available: set {ENV} to the path of {FILE_NAME} "
        f"(Seeed's XIAO UF2 bootloader, sha256 {SHA256[:16]}...)"
    )


def path() -> Path | None:
    """The .bin MC_BOOTLOADER names, or None when it is unset or empty."""
    p = os.environ.get(ENV, "").strip()
    return Path(p) if p else None


def load(where: str | Path | None = None) -> bytes:
    """The pinned bootloader's bytes (from `where`, else MC_BOOTLOADER); BootloaderError saying why not."""
    p = Path(where) if where is not None else path()
    if p is None:
        raise BootloaderError(unavailable())
    try:
        data = p.read_bytes()
    except OSError as e:
        raise BootloaderError(f"{ENV}={p}: cannot read it ({e.strerror or e})") from None
    digest = hashlib.sha256(data).hexdigest()
    if digest != SHA256:
        raise BootloaderError(f"{ENV}={p}: sha256 {digest} is not the XIAO bootloader's ({SHA256}): refused")
    return data


# ---------------------------------------------------------------- cycle costs of the bootloader's code

_LINE = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f]{4}(?: [0-9a-f]{4})?)\s*\t(\S+)\s*(.*)$")


def _objdump(binfile: str, start: int) -> str:
    cmd = ["arm-none-eabi-objdump", "-D", "-b", "binary", "-marm", "-Mforce-thumb", f"--start-address={start:#x}"]
    try:
        return subprocess.run([*cmd, binfile], capture_output=True, text=True, check=True).stdout
    except FileNotFoundError:
        raise BootloaderError(
            "arm-none-eabi-objdump not found (Debian gcc-arm-none-eabi): no cycle costs for the bootloader"
        ) from None


@lru_cache(maxsize=4)
def sweep(data: bytes) -> tuple[cycles.Insn, ...]:
    """The instructions of a raw Thumb binary at address 0: a linear sweep, restarted past any 32-bit encoding that
    ARMv6-M does not have (data taken for code)."""
    out: list[cycles.Insn] = []
    with tempfile.NamedTemporaryFile(suffix=".bin") as f:
        f.write(data)
        f.flush()
        start = 0
        while start < len(data):
            restart = None
            for ln in _objdump(f.name, start).splitlines():
                m = _LINE.match(ln)
                if not m:
                    continue
                addr, raw, mnem, rest = int(m.group(1), 16), m.group(2), m.group(3), m.group(4)
                if mnem.startswith((".", "<")):
                    continue
                mnem = mnem.removesuffix(".n").removesuffix(".w")
                if " " in raw and mnem not in cycles.WIDE:
                    restart = addr + 2
                    break
                ops, _, comment = rest.partition("@")
                out.append(cycles.Insn(addr, mnem, ops.strip(), comment.strip()))
            if restart is None:
                break
            start = restart
    return tuple(out)


def boot_tables(boot: bytes, app: cycles.Image | None = None) -> cycles.BlockTables:
    """The cycle tables of a board's flash with the bootloader at 0 and the application `app` (its disassembly;
    None: a blank board). THE seam for the cost model of code not loaded from an ELF: replace this function."""
    functions = dict(app.functions) if app is not None else {}
    by_addr = dict(app.by_addr) if app is not None else {}
    words = dict(app.words) if app is not None else {}
    functions["uf2_bootloader"] = Function("uf2_bootloader", 0, list(sweep(boot)))
    by_addr[0] = "uf2_bootloader"
    return cycles.block_tables(cycles.Image(functions, by_addr, words))
