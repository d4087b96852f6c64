"""Build the flashed images (one per cell address, and the primary) with PlatformIO, as the flash tool builds them.

``metacell_common.target.build.board_build_env`` is the one definition of a board's build: the PlatformIO environment,
its own build directory and the source-only flags that give a cell its number and I2C address; the flash tool
uploads exactly these builds and the image tier runs them. ``build_images`` caches the ELFs by a hash of everything
the build reads (src/, lib/, platformio.ini, the build hooks) and builds offline through a pre-installed tree's
use.sh (MC_PIO_TREE) or with the user's own PlatformIO (~/.platformio holding the atmelsam platform), as
``metacell_common.target.pio.how_to_build`` says (the flash tool asks it too). Each cached ELF has its SHA-256 beside
it (``firmware.elf.sha256``, as sha256sum writes it), recorded when it was built (or, for a cache from before the
records, when first used); a cached ELF that no longer matches its record is refused (CorruptCacheError).
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from metacell_common import firmware
from metacell_common.target.build import board_build_env
from metacell_common.target.pio import how_to_build, pio_executable
from protocol.wire import N_CELLS

from . import ImageTierUnavailable
from .elfimage import ImageError

ROOT = Path(__file__).resolve().parents[2]
IMAGE_BUILD_INPUTS = ("src", "lib", "platformio.ini", "metacell_tools/flash/pio_fwcheck.py")


class ImageBuildError(ImageTierUnavailable):
    """The images cannot be built here (no PlatformIO tree) or their build failed."""


def inputs_digest(root: Path = ROOT) -> str:
    h = hashlib.sha256()
    for name in IMAGE_BUILD_INPUTS:
        p = root / name
        files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        for f in files:
            if "__pycache__" in f.parts:
                continue
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


class CorruptCacheError(ImageError):
    """A cached ELF is not the file that was built (its SHA-256 differs from the one recorded beside it)."""


def sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def digest_record(elf: Path) -> Path:
    return elf.with_name(elf.name + ".sha256")


def record_digest(elf: Path) -> None:
    """Write the ELF's SHA-256 beside it (atomically: parallel test workers may record the same file)."""
    rec = digest_record(elf)
    tmp = rec.with_name(f"{rec.name}.{os.getpid()}.tmp")
    tmp.write_text(f"{sha256_file(elf)}  {elf.name}\n")
    os.replace(tmp, rec)


def check_cached(elf: Path) -> None:
    """CorruptCacheError (one line) when a cached ELF differs from its recorded SHA-256; a cache from before the
    records gets its record now."""
    rec = digest_record(elf)
    if not rec.is_file():
        record_digest(elf)
        return
    want = rec.read_text(errors="replace").split(maxsplit=1)
    got = sha256_file(elf)
    if not want or want[0] != got:
        raise CorruptCacheError(
            f"{elf}: SHA-256 {got[:16]}... is not the {want[0][:16] if want else 'empty'}... recorded when it was "
            f"built: the image cache is corrupted (delete {elf.parents[1]} to rebuild it)"
        )


@dataclass(frozen=True)
class ImageSet:
    cells: tuple[Path, ...]  # cell j's ELF at index j - 1
    primary: Path
    digest: str


def cache_dir() -> Path:
    return firmware.BUILD_DIR.parent / "image-elf"


class BuildProgress:
    """What a build of the flashed images says while it runs (minutes the first time): a line when it starts, then a
    bar with one step per board and the time left (tqdm, on a terminal); elsewhere (a pipe, a log) one line per
    board built with its time and an estimate of the rest (the boards still to build at the last board's time: the
    first one also builds the shared core and library and takes longest)."""

    def __init__(self, total: int, where: str, quiet: bool = False, file=None) -> None:
        from metacell_common.progress import bar

        self.total, self.done, self.quiet = total, 0, quiet
        self.file = file or sys.stderr
        self.say(
            f"building {total} flashed image(s) with PlatformIO into {where} (once per change of src/, lib/ or "
            "platformio.ini; the first board takes longest)"
        )
        self.bar = bar(total, desc="flashed images", unit="board", quiet=quiet, file=self.file)

    def say(self, text: str) -> None:
        if not self.quiet:
            print(text, file=self.file, flush=True)

    def start(self, label: str) -> None:
        self.bar.set_postfix_str(f"building {label}", refresh=True)

    def built(self, label: str, seconds: float) -> None:
        self.done += 1
        self.bar.update(1)
        left = self.total - self.done
        if self.bar.disable:
            rest = f", about {left * seconds / 60:.1f} min left" if left else ""
            self.say(f"built {label} in {seconds:.1f} s ({self.done}/{self.total}{rest})")

    def close(self) -> None:
        self.bar.close()


def build_images(cells: int = N_CELLS, *, root: Path = ROOT, primary: bool = True, log=None, progress=None) -> ImageSet:
    """The ELFs of cells 1..cells and (unless primary is False) the primary, built now if the cache lacks them
    (ImageBuildError). Without the primary, ImageSet.primary names a file that may not exist.

    While it builds: `progress(k, total, label)` before each board when given, else a BuildProgress on stderr."""
    if not 1 <= cells <= N_CELLS:
        raise ValueError(f"cells = {cells}: expected 1..{N_CELLS}")
    digest = inputs_digest(root)
    out = cache_dir() / digest
    want = [("cell", j) for j in range(1, cells + 1)] + ([("primary", None)] if primary else [])

    def elf(role, j):
        return out / (f"cell{j:02d}" if role == "cell" else "primary") / "firmware.elf"

    if all(elf(r, j).is_file() for r, j in want):
        for role, j in want:
            check_cached(elf(role, j))
        return ImageSet(tuple(elf("cell", j) for j in range(1, cells + 1)), elf("primary", None), digest)
    prefix, why = how_to_build(root)
    if prefix is None:
        raise ImageBuildError(why)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # parallel test workers build once
        todo = [(role, j) for role, j in want if not elf(role, j).is_file()]  # another worker may have built some
        shown = BuildProgress(len(todo), str(out)) if todo and progress is None else None
        try:
            for k, (role, j) in enumerate(want):
                if elf(role, j).is_file():
                    check_cached(elf(role, j))
                    continue
                label = "primary" if role == "primary" else f"cell {j}"
                if progress:
                    progress(k, len(want), label)
                if shown:
                    shown.start(label)
                t0 = time.monotonic()
                _build_one(root, out, role, j, prefix, elf(role, j), log)
                if shown:
                    shown.built(label, time.monotonic() - t0)
        finally:
            if shown:
                shown.close()
    return ImageSet(tuple(elf("cell", j) for j in range(1, cells + 1)), elf("primary", None), digest)


def _build_one(root: Path, out: Path, role: str, j: int | None, prefix: list, dest: Path, log) -> None:
    """One board's `pio run` into the cache (dest); ImageBuildError with the end of its log if it fails."""
    # every cell builds in one directory (only src/, whose flags name the cell, recompiles; the core and the
    # library are shared): the loaded segments are those of a clean build (tests/host_emulator/image)
    env_name, env_vars = board_build_env(role, j, root, build_root=out / "pio-build")
    if role == "cell":
        env_vars = (("PLATFORMIO_BUILD_DIR", str(out / "pio-build" / "build-cells")), env_vars[1])
    env = dict(os.environ)
    env.update(env_vars)
    pio = pio_executable()
    env.update(
        PIO=str(pio),
        PATH=f"{pio.parent}{os.pathsep}{env.get('PATH', '')}",
        PIO_OFFLINE_WORK=str(out / "pio-work"),
    )
    t0 = time.monotonic()
    r = subprocess.run([*prefix, "run", "-e", env_name], cwd=root, env=env, capture_output=True, text=True)
    logtext = r.stdout + r.stderr
    if log:
        log(f"built {role}{'' if j is None else f' {j}'} in {time.monotonic() - t0:.1f} s")
    if r.returncode != 0:
        raise ImageBuildError(f"pio run -e {env_name} ({role} {j or ''}) failed:\n{logtext[-4000:]}")
    built = Path(dict(env_vars)["PLATFORMIO_BUILD_DIR"]) / env_name / "firmware.elf"
    if not built.is_file():
        raise ImageBuildError(f"pio run -e {env_name} left no {built}")
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(built, dest)
    record_digest(dest)
