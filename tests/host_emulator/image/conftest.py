"""Fixtures of the image tier's tests: the flashed images (built once, or a one-line skip), booted worlds, and
scratch copies of the firmware project that mutation tests break on purpose."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from host_emulator.image import build, regtable
from host_emulator.image.laptop import Laptop
from host_emulator.image.model import bring_up
from host_emulator.image.world import World, WorldConfig
from host_emulator.params import Params

ROOT = Path(__file__).resolve().parents[3]


def images_or_skip(cells: int = 16, root: Path = ROOT, primary: bool = True) -> build.ImageSet:
    """The images (built now if the cache lacks them); a skip naming why when PlatformIO cannot build them."""
    prefix, why = build.how_to_build(root)
    try:
        images = build.build_images(cells, root=root, primary=primary)
    except build.ImageBuildError:
        if prefix is None:
            pytest.skip(f"image tier skipped: {why}")
        raise
    try:  # cached images without the tree that built them: the register table has no headers to come from
        regtable.find_include_dirs()
    except regtable.RegTableError as e:
        if prefix is None:
            pytest.skip(f"image tier skipped: {e}")
        raise
    return images


@pytest.fixture(scope="session")
def images() -> build.ImageSet:
    return images_or_skip(16)


def configured(
    images: build.ImageSet,
    cells: int,
    config: WorldConfig | None = None,
    params: Params | None = None,
    start_plant: bool = True,
) -> tuple[World, Laptop]:
    """A world of `cells` cells and the primary brought up as a run does (model.bring_up: USB, every cell configured
    and enabled), the plant started (optional)."""
    p = params or Params(cells=cells)
    w = World(p, images, config=config or WorldConfig())
    lap, up = bring_up(w, p)
    assert not up["refused"], up
    if start_plant:
        w.start_plant()
    return w, lap


class Scratch:
    """A copy of the firmware project (src/, lib/, platformio.ini, the build hook) to break on purpose."""

    def __init__(self, where: Path) -> None:
        self.root = where
        for name in build.IMAGE_BUILD_INPUTS:
            src, dst = ROOT / name, where / name
            dst.parent.mkdir(parents=True, exist_ok=True)
            if src.is_dir():
                shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))
            else:
                shutil.copy2(src, dst)

    def replace(self, rel: str, old: str, new: str, count: int = 1) -> None:
        """Replace `old` by `new` in one file of the copy; the text must occur exactly `count` times (a mutation
        that no longer finds its target fails loudly instead of testing nothing)."""
        f = self.root / rel
        text = f.read_text()
        n = text.count(old)
        assert n == count, f"{rel}: {old!r} occurs {n} times, expected {count}: the mutation's target moved"
        f.write_text(text.replace(old, new))

    def sub(self, rel: str, pattern: str, new: str) -> None:
        f = self.root / rel
        text, n = re.subn(pattern, new, f.read_text(), flags=re.M)
        assert n == 1, f"{rel}: {pattern!r} matched {n} times, expected 1: the mutation's target moved"
        f.write_text(text)

    def revert(self, commit: str, path: str = "src") -> None:
        """Undo a commit's change to `path` in the copy (its diff applied in reverse, from this repository's
        history)."""
        diff = subprocess.run(
            ["git", "-C", str(ROOT), "show", "--format=", commit, "--", path],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        assert diff.strip(), f"commit {commit} changes nothing under {path}"
        r = subprocess.run(
            ["patch", "-R", "-p1", "--no-backup-if-mismatch", "-d", str(self.root)],
            input=diff,
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, f"reverting {commit} no longer applies:\n{r.stdout}{r.stderr}"

    def images(self, cells: int = 1, primary: bool = True) -> build.ImageSet:
        return images_or_skip(cells, self.root, primary)


@pytest.fixture
def scratch(tmp_path) -> Scratch:
    if build.how_to_build(ROOT)[0] is None:
        pytest.skip(f"image tier skipped: {build.how_to_build(ROOT)[1]}")
    return Scratch(tmp_path / "project")
