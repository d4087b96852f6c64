"""The XIAO's UF2 bootloader in the image tier: found through MC_BOOTLOADER and pinned by its hash.

The boards ship with Seeed's build of the UF2 bootloader (uf2-samdx1 v3.7.0-33-g90ff611, 8,192 bytes at flash
0x0000-0x1FFF). No package registry has it, so the tier finds the .bin through the environment variable
``MC_BOOTLOADER`` (its path) and runs only that exact file (its sha256 is pinned: the times and
addresses the tests expect of it are per binary). With ``boot = "bootloader"`` (``WorldConfig.boot``, the scene key
``model_options.image.boot``) a board runs it from the reset vector and the bootloader starts the application at
0x2000 by itself; with ``boot = "direct"`` (the default) the tier starts the application directly, as before.

Cycle costs: the bootloader has no ELF, so no tables; the board's cost decoder (``csrc/sam_cost.c``, its table
generated from the one cycle model by ``costtable.py``) costs its blocks from the flash bytes, as it does any code
outside an ELF's tables (``tests/host_emulator/image/test_cost.py`` checks it on the bootloader's reachable code).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

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
