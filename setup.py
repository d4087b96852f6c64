"""Packaging hook: the wheel carries the firmware library's C sources (lib/metacell) as host_emulator package data.

The emulator compiles lib/metacell with cffi at first use; from a wheel there is no source checkout, so
build_py copies lib/metacell (sources, headers, library.json) to host_emulator/_lib/metacell inside the
package. Everything else about the project is in pyproject.toml.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
FIRMWARE = HERE / "lib" / "metacell"
PATTERNS = ("*.c", "*.h", "library.json")


def firmware_files() -> list[Path]:
    """The files of lib/metacell the host build needs, relative to lib/metacell (sorted)."""
    return sorted({p.relative_to(FIRMWARE) for pat in PATTERNS for p in FIRMWARE.rglob(pat) if p.is_file()})


class BuildPyWithFirmware(build_py):
    """build_py, then lib/metacell into <build>/host_emulator/_lib/metacell (not in editable mode: there the
    checkout's own lib/ is used)."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        if not FIRMWARE.is_dir():
            raise SystemExit(f"packaging: {FIRMWARE} is missing: build the wheel from a full source checkout")
        dest = Path(self.build_lib) / "host_emulator" / "_lib" / "metacell"
        for rel in firmware_files():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(FIRMWARE / rel, dest / rel)


setup(cmdclass={"build_py": BuildPyWithFirmware})
