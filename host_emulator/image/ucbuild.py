"""The image tier's Unicorn: the pinned release's source with this project's patches (ucpatches/), built for ARM.

    python -m host_emulator.image.ucbuild            # build it if it is missing (make setup runs this)
    python -m host_emulator.image.ucbuild --where    # print where it is, or exit 1 when it is not built

Unicorn 2.1.4 as released spends much of the image tier's time where this tier cannot reach through its API
(docs/image-tier.md, "The tier's Unicorn"): peripheral pages refilled in its TLB, Handler-mode returns through its
main loop, block lookups across 1 KiB pages, an exit check after every load and store and at every block's
start, a page-map walk and QEMU's generic dispatch at every peripheral access, and a dispatch per register where
the tier reads the core's registers (0007 adds uc_arm_m_core_read to the public header, the one addition; the
tier's code uses the batch read where the header lacks it). The patches (one file each, a header saying what and why)
change only how fast Unicorn reaches a result, never the result:
tests/host_emulator/image/test_world.py::test_the_released_unicorn_gives_the_same_run runs three cells and the
primary on this build and on the released wheel (MC_UNICORN=stock) and compares every board's change of state,
cycle counts, fast-forward counters and the plant, bit for bit.

The source is the release's source distribution, fetched with pip (the package index the project's other
dependencies come from) and checked against SDIST_SHA256; only ARM is compiled (about a minute on two cores). The
result, libunicorn.a and its headers, goes to build/unicorn/<key>/ (MC_UNICORN_DIR moves it; the key hashes the
release, the patches and the build options: a changed patch builds anew, the old build stays until `make clean`).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

from metacell_common import firmware

from .build import sha256_file

VERSION = "2.1.4"
SDIST = f"unicorn-{VERSION}.tar.gz"
SDIST_SHA256 = "00567a70e323f749b419cd86bee4f9115beab7ebba32194581c090cbb7c59cff"
PATCH_DIR = Path(__file__).resolve().parent / "ucpatches"
CMAKE_OPTIONS = ("-DCMAKE_BUILD_TYPE=Release", "-DUNICORN_BUILD_TESTS=off", "-DUNICORN_ARCH=arm")


class UnicornBuildError(RuntimeError):
    """The patched Unicorn could not be fetched, patched or built (one line: which step, and why)."""


def patches() -> list[Path]:
    """The patches in the order they are applied (their names' order)."""
    return sorted(PATCH_DIR.glob("*.patch"))


def key() -> str:
    """16 hex digits naming a build: the release, its digest, every patch (name and bytes), the build options."""
    h = hashlib.sha256(f"{VERSION} {SDIST_SHA256} {' '.join(CMAKE_OPTIONS)}".encode())
    for p in patches():
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def prefix() -> Path:
    """Where this source tree's patched Unicorn is (or goes): build/unicorn/<key> in a checkout, the user's cache
    from a wheel; MC_UNICORN_DIR moves it. MC_BUILD_DIR does not: the library is a part of the toolchain the builds
    under it use, not one of them."""
    where = os.environ.get("MC_UNICORN_DIR")
    return (Path(where) if where else firmware.default_build_dir().parent / "unicorn") / key()


def installed() -> tuple[Path, Path] | None:
    """(include dir, libunicorn.a) of the patched build, or None when it is not built."""
    p = prefix()
    inc, lib = p / "include", p / "lib" / "libunicorn.a"
    return (inc, lib) if (inc / "unicorn" / "unicorn.h").is_file() and lib.is_file() else None


def _run(cmd: list[str], cwd: Path, what: str, log: Path) -> None:
    with open(log, "ab") as out:
        r = subprocess.run(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        tail = log.read_text(errors="replace").strip().splitlines()[-1:] or [""]
        raise UnicornBuildError(f"unicorn: {what} failed (exit {r.returncode}; {tail[0].strip()}; log {log})")


def fetch_sdist(dest: Path, sdist: Path | None = None) -> Path:
    """The release's source distribution in dest, checked against SDIST_SHA256 (from `sdist` if given, else pip)."""
    if sdist is None:
        pip = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:", "-d", str(dest)]
        _run([*pip, f"unicorn=={VERSION}"], dest, f"pip download of unicorn=={VERSION}", dest / "pip.log")
        sdist = dest / SDIST
        if not sdist.is_file():
            raise UnicornBuildError(f"unicorn: pip download left no {SDIST} in {dest}")
    digest = sha256_file(sdist)
    if digest != SDIST_SHA256:
        raise UnicornBuildError(f"unicorn: {sdist} has sha256 {digest}, not the pinned {SDIST_SHA256}")
    return sdist


def _compile(src: Path, build: Path, log: Path, quiet: bool) -> None:
    """cmake configure and build, with a bar following cmake's own percentage."""
    from metacell_common.progress import bar

    _run(["cmake", "-B", str(build), "-S", str(src), *CMAKE_OPTIONS], src, "cmake configure", log)
    jobs = str(os.cpu_count() or 2)
    pb = bar(100, desc="unicorn (ARM)", unit="%", quiet=quiet)
    with open(log, "ab") as out:
        proc = subprocess.Popen(
            ["cmake", "--build", str(build), "-j", jobs], cwd=build, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
        )
        assert proc.stdout is not None
        for raw in proc.stdout:
            out.write(raw)
            m = re.match(rb"\[\s*(\d+)%\]", raw)
            if m and int(m.group(1)) > pb.n:
                pb.update(int(m.group(1)) - pb.n)
        rc = proc.wait()
    pb.close()
    if rc != 0:
        raise UnicornBuildError(f"unicorn: compile failed (exit {rc}; log {log})")


def build(*, sdist: Path | None = None, quiet: bool = False) -> tuple[Path, Path]:
    """Fetch, check, patch and compile; install into prefix() (UnicornBuildError). Returns installed()."""
    done = installed()
    if done is not None:
        return done
    for tool in ("cmake", "patch"):
        if shutil.which(tool) is None:
            raise UnicornBuildError(f"unicorn: `{tool}` is not installed (make setup installs it)")
    dest = prefix()
    dest.parent.mkdir(parents=True, exist_ok=True)
    say = (lambda s: None) if quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    say(f"unicorn: building {VERSION} with {len(patches())} patch(es) for ARM into {dest} (once; about a minute)")
    with tempfile.TemporaryDirectory(prefix="unicorn-", dir=dest.parent) as tmp:
        work = Path(tmp)
        log = work / "build.log"
        archive = fetch_sdist(work, sdist)
        with tarfile.open(archive) as tf:
            tf.extractall(work, filter="data")
        src = work / f"unicorn-{VERSION}" / "src"
        if not (src / "CMakeLists.txt").is_file():
            raise UnicornBuildError(f"unicorn: {SDIST} has no src/CMakeLists.txt")
        for p in patches():
            _run(["patch", "-p1", "--forward", "--batch", "-i", str(p)], src, f"patch {p.name}", log)
        _compile(src, work / "build", log, quiet)
        stage = work / "install"
        (stage / "lib").mkdir(parents=True)
        shutil.copy2(work / "build" / "libunicorn.a", stage / "lib" / "libunicorn.a")
        shutil.copytree(src / "include" / "unicorn", stage / "include" / "unicorn")
        for p in patches():
            shutil.copy2(p, stage / p.name)  # what this build carries, beside it
        try:
            os.rename(stage, dest)  # atomic: a build is whole or absent (another process may have won the race)
        except OSError:
            if installed() is None:
                raise
    got = installed()
    if got is None:
        raise UnicornBuildError(f"unicorn: {dest} is incomplete after the build")
    say(f"unicorn: built {got[1]}")
    return got


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.image.ucbuild", description=__doc__.splitlines()[0])
    ap.add_argument("--where", action="store_true", help="print the build's directory; exit 1 if it is not built")
    ap.add_argument("--sdist", type=Path, help=f"use this {SDIST} instead of fetching it (its sha256 is checked)")
    ap.add_argument("--quiet", action="store_true", help="no progress (errors still print)")
    a = ap.parse_args(argv)
    if a.where:
        got = installed()
        print(prefix() if got else f"not built: {prefix()}")
        return 0 if got else 1
    try:
        build(sdist=a.sdist, quiet=a.quiet)
    except UnicornBuildError as e:
        print(e, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
