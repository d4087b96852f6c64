"""The patched Unicorn's build (image/ucbuild.py) and the runtime's choice of library (MC_UNICORN); that the patched
library gives the same runs as the released one is test_world.py's `test_the_released_unicorn_gives_the_same_run`."""

from __future__ import annotations

import hashlib
import shutil
import tarfile
from pathlib import Path

import pytest

from host_emulator.image import runtime, ucbuild


def test_the_key_follows_every_patch_and_nothing_else(tmp_path, monkeypatch):
    """A build is named by the release and each patch's name and bytes: a changed, added or renamed patch builds
    anew (never links a stale library); the same patches copied elsewhere name the same build."""
    for p in ucbuild.patches():
        shutil.copy(p, tmp_path / p.name)
    monkeypatch.setattr(ucbuild, "PATCH_DIR", tmp_path)
    k0 = ucbuild.key()
    monkeypatch.undo()
    assert ucbuild.key() == k0
    monkeypatch.setattr(ucbuild, "PATCH_DIR", tmp_path)
    first = sorted(tmp_path.glob("*.patch"))[0]
    first.write_bytes(first.read_bytes() + b"\n")
    k1 = ucbuild.key()
    first.rename(tmp_path / ("z" + first.name))
    k2 = ucbuild.key()
    (tmp_path / "0009-more.patch").write_text("--- a/x\n+++ b/x\n")
    k3 = ucbuild.key()
    assert len({k0, k1, k2, k3}) == 4


def test_the_patches_are_headed_edit_qemu_and_only_add_to_the_public_header():
    """Each patch opens with a line saying what it changes and a paragraph saying why, and edits files of the
    release's QEMU tree (the -p1 paths under src/ that the build applies them in); the public header only gains
    lines (an addition the tier's code uses where it is defined, the released library staying usable), never loses
    or changes one."""
    ps = ucbuild.patches()
    assert len(ps) >= 3
    for p in ps:
        text = p.read_text()
        head = text.split("\n--- ", 1)[0]
        assert head.splitlines()[0].endswith(")."), p.name  # "What it does (file, function)."
        assert len(head.split()) > 60, p.name  # and why, in words
        targets = [ln[4:].split("\t")[0] for ln in text.splitlines() if ln.startswith("+++ ")]
        assert targets and all(t.startswith(("b/qemu/", "b/include/unicorn/")) for t in targets), (p.name, targets)
        for part in text.split("\n--- ")[1:]:
            if part.startswith("a/include/unicorn/"):
                removed = [ln for ln in part.splitlines()[2:] if ln.startswith("-")]
                assert not removed, (p.name, removed)


def _fake_sdist(tmp_path: Path) -> Path:
    src = tmp_path / f"unicorn-{ucbuild.VERSION}" / "src"
    src.mkdir(parents=True)
    (src / "CMakeLists.txt").write_text("project(x)\n")
    out = tmp_path / ucbuild.SDIST
    with tarfile.open(out, "w:gz") as tf:
        tf.add(tmp_path / f"unicorn-{ucbuild.VERSION}", arcname=f"unicorn-{ucbuild.VERSION}")
    return out


def test_an_sdist_that_is_not_the_pinned_one_is_refused_and_nothing_installed(tmp_path, monkeypatch):
    """A source archive whose sha256 is not the pinned one stops the build in one line naming both digests, before
    anything is extracted or compiled; no build appears where the runtime looks."""
    monkeypatch.setenv("MC_UNICORN_DIR", str(tmp_path / "build" / "unicorn"))
    fake = _fake_sdist(tmp_path)
    with pytest.raises(ucbuild.UnicornBuildError) as e:
        ucbuild.build(sdist=fake, quiet=True)
    msg = str(e.value)
    assert "\n" not in msg and ucbuild.SDIST_SHA256 in msg
    assert hashlib.sha256(fake.read_bytes()).hexdigest() in msg
    assert ucbuild.installed() is None
    assert not list((tmp_path / "build" / "unicorn").glob("*/lib"))  # no partial build left where it is looked for
    assert ucbuild.main(["--where"]) == 1
    assert ucbuild.main(["--sdist", str(fake), "--quiet"]) == 2


def test_the_runtime_links_the_patched_build_unless_told_otherwise(monkeypatch):
    """MC_UNICORN unset or 'patched': the build under build/unicorn/<key>; 'stock': the released wheel's library;
    anything else: a one-line error. A missing patched build is a one-line error naming how to build it."""
    monkeypatch.delenv(runtime.UNICORN_ENV, raising=False)
    got = ucbuild.installed()
    if got is None:
        with pytest.raises(runtime.RuntimeBuildError, match="make setup"):
            runtime.unicorn_paths()
    else:
        assert runtime.unicorn_paths() == got
        assert got[1].is_relative_to(ucbuild.prefix())
    monkeypatch.setenv(runtime.UNICORN_ENV, "stock")
    inc, lib = runtime.unicorn_paths()
    assert (inc / "unicorn" / "unicorn.h").is_file() and lib.name == "libunicorn.a"
    assert not lib.is_relative_to(ucbuild.prefix().parent)
    monkeypatch.setenv(runtime.UNICORN_ENV, "fast")
    with pytest.raises(runtime.RuntimeBuildError) as e:
        runtime.unicorn_paths()
    assert "\n" not in str(e.value) and "'fast'" in str(e.value)
    monkeypatch.setattr(ucbuild, "installed", lambda: None)
    monkeypatch.setenv(runtime.UNICORN_ENV, "patched")
    with pytest.raises(runtime.RuntimeBuildError, match="python -m host_emulator.image.ucbuild"):
        runtime.unicorn_paths()
