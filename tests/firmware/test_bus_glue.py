"""The glue in src/ compiles against the library headers and the stand-in Arduino/Wire/SAMD21 headers."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


GLUE = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "src").rglob("*.cpp"))


@pytest.mark.skipif(not shutil.which("g++"), reason="no host C++ compiler")
@pytest.mark.parametrize("src", GLUE)
# a plain `pio run` image (cell 0, bus off) and a per-cell image as metacell_tools.flash builds it
@pytest.mark.parametrize("defines", [[], ["-DMC_CELL_INDEX=16", "-DMC_CELL_ADDR=0x1f"]], ids=["plain", "cell16"])
def test_glue_compiles(src, defines):
    """Catches drift between lib/metacell's API, the stand-in registers and src/ (the real build is in
    test_pio_build.py, where PlatformIO runs)."""
    res = subprocess.run(
        [
            "g++",
            "-std=gnu++11",
            "-fsyntax-only",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-I",
            str(ROOT / "tests/stubs/arduino"),
            "-I",
            str(ROOT / "lib/metacell/src"),
            "-I",
            str(ROOT / "src"),
            "-I",
            str(ROOT / "src/cell"),
            *defines,
            str(ROOT / src),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
