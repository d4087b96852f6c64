"""Before touching a board: can this machine build the images (PlatformIO) and upload them (its tool-bossac, or bossac)?

The flash tool builds through an offline PlatformIO tree's use.sh when MC_PIO_TREE names one, else with the user's
PlatformIO (~/.platformio holding the atmelsam platform): metacell_common.target.pio decides, as for the image tier.
It uploads with PlatformIO's own uploader when its tool-bossac package is installed (`pio run -t upload`), else with a
bossac on PATH (Debian's bossa-cli 1.9.1: touch, bootloader port, `--offset=0x2000`; see bossac.py). What is missing
is one line (PreflightError), said before the first board is touched.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from metacell_common.target.pio import how_to_build, offline_tree, packages_dir

APP_OFFSET = 0x2000  # the UF2 bootloader holds flash 0x0000-0x1FFF; the core links the application at 0x2000
FLASH_ROW = 0x100  # the SAMD21's erase unit (4 pages of 64 bytes)
PIO_BOSSAC = "tool-bossac"
# the version atmelsam 8.3.0 asks for a SAMD21 board (platform.json ~1.10700.0: bossac 1.7, which knows the
# XIAO's offset by itself); PlatformIO downloads it on the first upload when it is not installed
PIO_BOSSAC_SPEC = "~1.10700.0"
UPLOADERS = ("auto", "pio", "bossac")
GET_BOSSAC = "install Debian's bossac: sudo apt-get install bossa-cli (make setup does it)"
GET_PIO_BOSSAC = f"online: pio pkg install -g -t platformio/{PIO_BOSSAC}@{PIO_BOSSAC_SPEC}"


class PreflightError(ValueError):
    """This machine cannot build or upload the images; the message is one line naming what is missing."""


@dataclass(frozen=True)
class Toolchain:
    pio: str  # the PlatformIO executable, as named (--pio, MC_PIO) or found
    build_prefix: tuple[str, ...]  # runs `pio ARGS`: (pio,) or the offline tree's (bash, use.sh, TREE, PROJECT)
    build_env: tuple[tuple[str, str], ...]  # set for each PlatformIO run (the tree's PIO and its kept work dir)
    uploader: str  # "pio": PlatformIO's tool-bossac (`-t upload`); "bossac": touch + bossac
    bossac: str | None = None  # the bossac executable (uploader "bossac")
    offset: int = APP_OFFSET  # where bossac writes the application

    @property
    def through_tree(self) -> bool:
        return self.build_prefix[:1] == ("bash",)

    def describe(self) -> str:
        build = "PlatformIO through MC_PIO_TREE's use.sh" if self.through_tree else f"PlatformIO ({self.pio})"
        return f"build: {build}; upload: {self.describe_upload()}"

    def describe_upload(self) -> str:
        if self.uploader == "pio":
            return f"PlatformIO's uploader ({PIO_BOSSAC})"
        return f"bossac ({self.bossac}) at offset 0x{self.offset:x}, after a 1200-baud touch"


def check_offset(offset: int, overwrite_bootloader: bool = False) -> str:
    """Empty string when bossac may write the application at offset, else the one-line refusal."""
    if offset < 0 or offset % FLASH_ROW:
        return f"--offset 0x{offset:x}: must be a multiple of 0x{FLASH_ROW:x} (a flash row) and not negative"
    if offset < APP_OFFSET and not overwrite_bootloader:
        return (
            f"--offset 0x{offset:x} would overwrite the XIAO's bootloader (flash 0x0000-0x{APP_OFFSET - 1:04X}); "
            f"the application belongs at 0x{APP_OFFSET:x} (--overwrite-bootloader forces it: the board then never "
            "comes back over USB)"
        )
    return ""


def pio_bossac_installed(packages: Path) -> bool:
    """PlatformIO's tool-bossac of the version atmelsam wants for the XIAO is in this packages dir."""
    for d in sorted(packages.glob(f"{PIO_BOSSAC}*")) if packages.is_dir() else []:
        try:
            version = str(json.loads((d / "package.json").read_text()).get("version", ""))
        except (OSError, ValueError):
            continue
        if version.startswith("1.107"):
            return True
    return False


def _resolve(exe: str, which: Callable[[str], str | None]) -> str | None:
    if os.sep in exe:
        return exe if Path(exe).is_file() else None
    return which(exe)


def find_toolchain(
    pio: str,
    project: Path,
    *,
    uploader: str = "auto",
    bossac: str | None = None,
    offset: int = APP_OFFSET,
    which: Callable[[str], str | None] = shutil.which,
    build: bool = True,
) -> Toolchain:
    """How this machine builds and uploads, or PreflightError naming everything that is missing (one line).
    build False: the images are prebuilt (PlatformIO is not needed)."""
    if uploader not in UPLOADERS:
        raise ValueError(f"uploader {uploader!r}: expected one of {UPLOADERS}")
    problems = []
    prefix: tuple[str, ...] = ()
    env: tuple[tuple[str, str], ...] = ()
    found = _resolve(pio, which) if build else None
    if not build:
        pass
    elif found is None:
        problems.append(
            f"cannot build: PlatformIO ({pio}) not found (pip install platformio==6.2.0; make setup puts it in .venv; "
            "or name it with --pio)"
        )
    else:
        cmd, why = how_to_build(project, Path(found), who="flash")
        if cmd is None:
            problems.append(why if why.startswith("flash cannot build") else f"cannot build: {why}")
        elif cmd[0] == "bash":  # the offline tree: its use.sh runs $PIO; a kept work dir keeps rebuilds incremental
            prefix = tuple(cmd)
            env = (("PIO", str(Path(found).absolute())), ("PIO_OFFLINE_WORK", str(Path(project) / ".pio" / "offline")))
        else:
            prefix = (pio,)
    packages = packages_dir()
    has_pio_bossac = pio_bossac_installed(packages)
    bossac_name = bossac or os.environ.get("MC_BOSSAC") or "bossac"
    bossac_path = _resolve(bossac_name, which)
    where = f"MC_PIO_TREE's {packages}" if offline_tree() is not None else str(packages)
    use = ""
    if uploader in ("auto", "pio") and has_pio_bossac:
        use = "pio"
    elif uploader in ("auto", "bossac") and bossac_path:
        use = "bossac"
    elif uploader == "pio":
        problems.append(
            f"cannot upload: PlatformIO's uploader ({PIO_BOSSAC} {PIO_BOSSAC_SPEC}) is not in {where} "
            f"({GET_PIO_BOSSAC}; or --uploader bossac)"
        )
    elif uploader == "bossac":
        problems.append(f"cannot upload: {bossac_name} not found ({GET_BOSSAC}; or name it with --bossac)")
    else:
        problems.append(
            f"cannot upload: neither PlatformIO's uploader ({PIO_BOSSAC}, not in {where}) nor bossac "
            f"({bossac_name}, not found) is installed; {GET_BOSSAC}"
        )
    if use == "pio" and offset != APP_OFFSET:
        problems.append(
            f"--offset applies to bossac uploads only (add --uploader bossac); PlatformIO's uploader "
            f"writes at 0x{APP_OFFSET:x}"
        )
    if problems:
        raise PreflightError("; ".join(problems))
    return Toolchain(pio, prefix, env, use, bossac_path if use == "bossac" else None, offset)
