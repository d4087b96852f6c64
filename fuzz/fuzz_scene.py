"""Atheris (libFuzzer for Python) on the scene parser (scene.load_scene, as `run`, `serve` and `design` load a scene
file): any bytes, with `--set` overrides taken from the lines that start with "#set ", give either a Scene or the
one-line errors the commands print (ConfigError, and the ValueError/KeyError they also turn into exit 2); anything
else is a finding. Seeds in fuzz/corpus/scene/. Run: python fuzz/fuzz_scene.py [libFuzzer options] [corpus]."""

import os
import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

with atheris.instrument_imports(include=["host_emulator.scene", "host_emulator.models.options"]):
    from host_emulator.scene import load_scene

# the scene file: in memory (a memfd), so that nothing is left behind when libFuzzer exits the process
FD = os.memfd_create("fuzz-scene")
FILE = f"/proc/self/fd/{FD}"


def test_one_input(data: bytes) -> None:
    overrides = [
        line[5:].decode("utf-8", "replace") for line in data.splitlines() if line.startswith(b"#set ") and len(line) > 5
    ]
    os.ftruncate(FD, 0)
    os.pwrite(FD, data, 0)
    try:
        scene = load_scene(FILE, overrides)
    except (ValueError, KeyError) as e:  # ConfigError is a ValueError
        assert "\n" not in str(e).strip(), str(e)
        return
    assert scene.cells >= 1 and scene.t_end_s > 0


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
