"""The image build says what it does while it runs: a line when it starts, then one per board with the time left
(here a stand-in for PlatformIO that writes an ELF, so nothing is compiled)."""

from __future__ import annotations

import sys

import pytest

from host_emulator.image import build

FAKE_PIO = """
import os, pathlib, sys
env = sys.argv[sys.argv.index("-e") + 1]
out = pathlib.Path(os.environ["PLATFORMIO_BUILD_DIR"]) / env
out.mkdir(parents=True, exist_ok=True)
(out / "firmware.elf").write_bytes(b"\\x7fELF fake")
"""


@pytest.fixture
def fake_pio(tmp_path, monkeypatch):
    script = tmp_path / "fake_pio.py"
    script.write_text(FAKE_PIO)
    monkeypatch.setattr(build, "how_to_build", lambda root: ([sys.executable, str(script)], ""))
    monkeypatch.setattr(build, "cache_dir", lambda: tmp_path / "image-elf")
    return tmp_path


def test_the_image_build_reports_each_board_and_the_time_left(fake_pio, capsys):
    s = build.build_images(3, primary=True)
    err = capsys.readouterr().err.splitlines()
    assert all(p.is_file() for p in (*s.cells, s.primary))
    assert err[0].startswith("building 4 flashed image(s) with PlatformIO into ")
    assert str(s.primary.parents[1]) in err[0]  # the cache directory of this digest
    boards = [line.split(" in ")[0] for line in err[1:]]
    assert boards == ["built cell 1", "built cell 2", "built cell 3", "built primary"], err
    assert "(1/4, about " in err[1] and " min left)" in err[1] and err[4].endswith("(4/4)"), err
    # cached: nothing to build, nothing said
    build.build_images(3, primary=True)
    assert capsys.readouterr().err == ""


def test_a_caller_with_its_own_progress_gets_the_calls_instead(fake_pio, capsys):
    calls = []
    build.build_images(2, primary=False, progress=lambda k, n, label: calls.append((k, n, label)))
    assert calls == [(0, 2, "cell 1"), (1, 2, "cell 2")] and capsys.readouterr().err == ""
