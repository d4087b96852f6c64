"""How to run PlatformIO for the XIAO builds here: an offline tree's use.sh (MC_PIO_TREE) or the user's ~/.platformio.

The image tier (host_emulator/image/build.py) and the flash tool (metacell_tools/flash) build the same images the
same way; both ask this module whether and how they can.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def pio_executable() -> Path:
    """The PlatformIO of this Python's environment (.venv/bin/pio beside .venv/bin/python)."""
    return Path(sys.executable).with_name("pio")


def offline_tree() -> Path | None:
    """The offline PlatformIO tree MC_PIO_TREE names, if any (not checked)."""
    tree = os.environ.get("MC_PIO_TREE")
    return Path(tree) if tree else None


def core_dir() -> Path:
    """The user's PlatformIO core dir: PLATFORMIO_CORE_DIR, else ~/.platformio."""
    return Path(os.environ.get("PLATFORMIO_CORE_DIR", Path.home() / ".platformio"))


def packages_dir() -> Path:
    """Where the PlatformIO that how_to_build runs finds its packages (the tree's, else the core dir's)."""
    tree = offline_tree()
    return tree / "packages" if tree is not None else core_dir() / "packages"


def how_to_build(
    root: Path = ROOT, pio: Path | None = None, who: str = "the image tier"
) -> tuple[list[str] | None, str]:
    """(command prefix to run ``pio ARGS``, "") or (None, the one-line reason the images cannot be built).

    pio: the PlatformIO executable (default pio_executable()); who: what cannot build, in that reason."""
    pio = pio_executable() if pio is None else pio
    if not pio.exists():
        return None, f"PlatformIO is not installed in {pio.parent} (pip install platformio==6.2.0)"
    tree = os.environ.get("MC_PIO_TREE")
    if tree:
        use = Path(tree) / "use.sh"
        if not use.is_file():
            return None, f"MC_PIO_TREE={tree} is not an offline PlatformIO tree (no use.sh)"
        return ["bash", str(use), str(Path(tree).resolve()), str(Path(root).resolve())], ""
    if (core_dir() / "platforms" / "atmelsam").is_dir():
        return [str(pio)], ""
    return None, (
        f"{who} cannot build the firmware images: no offline PlatformIO tree (set MC_PIO_TREE) and no "
        "~/.platformio with the atmelsam platform"
    )
