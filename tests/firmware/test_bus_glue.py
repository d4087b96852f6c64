"""The bus glue (src/cell/bus_glue.cpp, src/primary/*.cpp) compiles against the library headers and stand-in
Arduino/Wire headers."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(not shutil.which("g++"), reason="no host C++ compiler")
@pytest.mark.parametrize("src", ["src/cell/bus_glue.cpp", "src/primary/primary_hw.cpp", "src/primary/main.cpp"])
def test_bus_glue_compiles(src):
    res = subprocess.run(
        [
            "g++",
            "-std=gnu++11",
            "-fsyntax-only",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-I",
            str(ROOT / "tests/firmware/bus_stub"),
            "-I",
            str(ROOT / "lib/metacell/src"),
            "-I",
            str(ROOT / "src"),
            "-I",
            str(ROOT / "src/cell"),
            str(ROOT / src),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
