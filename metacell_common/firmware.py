"""Build the firmware library (and the emulator's compiled plant) for the host and load it with cffi.

It sits below the emulator and the laptop tools (host_emulator.firmware is its old name; fwcheck's golden vectors
call into the very module the emulator runs). The sources are files, not imports: lib/metacell (in a wheel, the
copy under host_emulator/_lib) and the emulator's C plant, host_emulator/csrc.

Like Klipper's chelper: the very C sources that ship on the cells are compiled
with the host compiler into one extension module, cached by a hash of the
sources. The FFI declarations are generated from the shipped headers
(preprocessed with ``-DMC_CDEF``), so there is no hand-kept copy of the API.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from .progress import bar

PKG = Path(__file__).resolve().parents[1] / "host_emulator"  # the emulator's package: its csrc/ and (wheel) _lib/
CHECKOUT = PKG.parent / "lib" / "metacell" / "src"  # a source checkout (also `pip install -e .`)
PACKAGED = PKG / "_lib" / "metacell" / "src"  # an installed wheel (setup.py copies lib/metacell here)
IN_CHECKOUT = CHECKOUT.is_dir()
LIB_SRC = CHECKOUT if IN_CHECKOUT else PACKAGED
ROOT = PKG.parent if IN_CHECKOUT else PKG  # source paths in the build hash are relative to this
HOST_CSRC = PKG / "csrc"


def default_build_dir() -> Path:
    """build/host in a checkout; from a wheel, the user's cache (site-packages may not be writable)."""
    if IN_CHECKOUT:
        return ROOT / "build" / "host"
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(cache) / "metacell-emulator" / "host"


BUILD_DIR = Path(os.environ.get("MC_BUILD_DIR") or default_build_dir())


class FirmwareBuildError(RuntimeError):
    """The host build of the firmware library cannot be made (sources missing, no C compiler, ...)."""


# Speed flags keep every float bit: no -ffast-math, no -march (FMA would fuse a*b+c), and -ffp-contract=off
# so no compiler ever contracts; -fvisibility=hidden and -flto let the tick inline the firmware's small calls
# (cffi reaches the functions from inside the module; only the module's init symbol is exported).
CFLAGS = [
    "-std=c99",
    "-O3",
    "-ffp-contract=off",
    "-fno-trapping-math",
    "-fvisibility=hidden",
    "-flto",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-fno-strict-aliasing",
]
LDFLAGS = ["-O3", "-flto", "-flto-partition=one", "-ffp-contract=off", "-fno-trapping-math"]
# MC_SANITIZE=1: the C (this library and the image tier's runtime, which builds with these flags) built with
# AddressSanitizer and UndefinedBehaviorSanitizer, every finding fatal; the flags are part of each build's key, so
# sanitized builds sit beside the normal ones. Python must then preload the ASan runtime (LD_PRELOAD of
# `cc -print-file-name=libasan.so`): tests/sanitize/ runs a set of tests so.
SANITIZE_FLAGS = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g"]
SANITIZE = os.environ.get("MC_SANITIZE") == "1"
if SANITIZE:  # -O1 and no LTO: a quicker build, and ASan's reports keep their lines
    CFLAGS = [f for f in CFLAGS if f not in ("-O3", "-flto")] + ["-O1", *SANITIZE_FLAGS]
    LDFLAGS = ["-O1", "-ffp-contract=off", "-fno-trapping-math", *SANITIZE_FLAGS]
# cffi's generated wrapper is not ISO C (it converts between object and function pointers), so -pedantic
# cannot join CFLAGS: our own sources get it in a syntax-only pass before each build.
PEDANTIC_FLAGS = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"]

_lock = threading.Lock()
_cache: dict[str, tuple[Any, Any]] = {}


def _tracked_filter(paths: list[Path]) -> list[Path]:
    """With MC_FW_TRACKED_ONLY=1, keep only files git tracks (skip others' work in progress)."""
    if os.environ.get("MC_FW_TRACKED_ONLY") != "1":
        return paths
    out = subprocess.run(["git", "-C", str(ROOT), "ls-files"], capture_output=True, text=True, check=True)
    tracked = {ROOT / line for line in out.stdout.splitlines()}
    return [p for p in paths if p in tracked]


def _sources() -> list[Path]:
    return _tracked_filter(sorted(LIB_SRC.rglob("*.c")) + sorted(HOST_CSRC.glob("*.c")))


def _headers() -> list[Path]:
    return _tracked_filter(sorted(LIB_SRC.rglob("*.h")) + sorted(HOST_CSRC.glob("*.h")))


def _digest(paths: list[Path]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(str(p.relative_to(ROOT)).encode())
        h.update(p.read_bytes())
    h.update(" ".join(CFLAGS + LDFLAGS).encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:16]


_DEFINE_RE = re.compile(
    r"^#define\s+(MC_[A-Z0-9_]+|HE_[A-Z0-9_]+)\s+\(?(-?(?:0x[0-9A-Fa-f]+|\d+))[uUlL]*\)?\s*(?:/\*.*)?$"
)


def cdef_source(headers: list[Path] | None = None) -> str:
    """Declarations of every shipped header, preprocessed for cffi."""
    headers = headers if headers is not None else _headers()
    cc = os.environ.get("CC", "cc")
    with tempfile.TemporaryDirectory() as tmp:
        fake = Path(tmp) / "inc"
        fake.mkdir()
        for name in ("stdint.h", "stddef.h", "stdbool.h"):
            (fake / name).write_text("")
        umbrella = Path(tmp) / "all.h"
        umbrella.write_text("".join(f'#include "{h}"\n' for h in headers))
        out = subprocess.run(
            [cc, "-E", "-P", "-nostdinc", "-I", str(fake), "-DMC_CDEF", str(umbrella)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    # integer-literal suffixes are C, not cffi
    out = re.sub(r"\b(\d+)[uU]\b", r"\1", out)
    defines = []
    seen = set()
    for h in headers:
        for line in h.read_text().splitlines():
            m = _DEFINE_RE.match(line.strip())
            if m and m.group(1) not in seen:
                seen.add(m.group(1))
                defines.append(f"#define {m.group(1)} {m.group(2)}")
    return "\n".join(defines) + "\n" + out


# Hashing every source costs ~2 ms; a sweep builds thousands of models, each asking for the build. A call
# within RECHECK_S of the previous check reuses its answer (an edit is seen by the next call after that).
RECHECK_S = 1.0
_last: list = [float("-inf"), None]  # [monotonic time of the last check, its (ffi, lib)]


def load() -> tuple[Any, Any]:  # (cffi FFI, compiled library)
    """Return (ffi, lib) of the host build, compiling it on first use."""
    if not LIB_SRC.is_dir() or not any(LIB_SRC.rglob("*.c")):
        raise FirmwareBuildError(
            f"the firmware sources are not here ({CHECKOUT} nor {PACKAGED}): the emulator compiles "
            "lib/metacell at first use; install a wheel built by `pip wheel .` from the repository (it carries "
            "them), or `pip install -e .` in a checkout"
        )
    now = time.monotonic()
    if _last[1] is not None and now - _last[0] < RECHECK_S:
        return _last[1]
    srcs = _sources()
    key = _digest(srcs + _headers())
    with _lock:
        if key not in _cache:
            mod = _build(srcs, key)
            _cache[key] = (mod.ffi, mod.lib)
        _last[0], _last[1] = time.monotonic(), _cache[key]
        return _cache[key]


def check_pedantic(srcs: list[Path], include_dirs: list[Path], defines: tuple[str, ...] = ()) -> None:
    """Compile `srcs` as ISO C99 (-pedantic, every warning an error) without generating code; raises on any."""
    cc = os.environ.get("CC", "cc")
    cmd = [cc, *PEDANTIC_FLAGS, *defines, *(f"-I{d}" for d in include_dirs), *map(str, srcs)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"C sources are not warning-free ISO C99:\n{r.stderr.strip()}")


class _compile_progress:
    """An elapsed-time bar while the library compiles (first use: about 30 s), on a terminal only."""

    def __enter__(self):
        self.bar = bar(
            None, desc="compiling the firmware library for the host (first use)", bar_format="{desc}: {elapsed}"
        )
        self.stop = threading.Event()

        def tick():
            while not self.stop.wait(0.5):
                self.bar.update(0.5)

        self.thread = threading.Thread(target=tick, daemon=True)
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()
        self.bar.close()
        return False


def _build(srcs: list[Path], key: str):
    name = f"_mcfw_{key}"
    outdir = BUILD_DIR / key
    so = next(outdir.glob(f"{name}*.so"), None) if outdir.exists() else None
    if so is None:
        import cffi

        check_pedantic(srcs, [LIB_SRC, HOST_CSRC])
        ffi = cffi.FFI()
        ffi.cdef(cdef_source())
        includes = "".join(f'#include "{h}"\n' for h in _headers())
        ffi.set_source(
            name,
            includes,
            sources=[str(s) for s in srcs],
            include_dirs=[str(LIB_SRC), str(HOST_CSRC)],
            extra_compile_args=CFLAGS,
            extra_link_args=LDFLAGS,
        )
        try:
            BUILD_DIR.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise FirmwareBuildError(f"cannot create the build directory {BUILD_DIR} ({e}); set MC_BUILD_DIR") from e
        tmp = Path(tempfile.mkdtemp(prefix="mcfw-", dir=BUILD_DIR.parent if BUILD_DIR.parent.exists() else None))
        try:
            try:
                with _compile_progress():
                    built = Path(ffi.compile(tmpdir=str(tmp), verbose=False))
            except Exception as e:  # cffi raises VerificationError/CompileError/LinkError; distutils may exit
                raise FirmwareBuildError(
                    f"compiling the firmware library for the host failed ({type(e).__name__}: {e}); it needs a C "
                    "compiler with LTO (gcc, `cc`) and the Python headers (Debian: apt-get install gcc python3-dev)"
                ) from e
            outdir.mkdir(parents=True, exist_ok=True)
            so = place_module(built, outdir)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return load_module(name, so)


def place_module(built: Path, outdir: Path) -> Path:
    """Copies a module cffi compiled into outdir under its own name, atomically (parallel test workers may build
    the same module at once): the path of the copy."""
    so = outdir / built.name
    part = outdir / f".{built.name}.{os.getpid()}"
    shutil.copy2(built, part)
    os.replace(part, so)
    return so


def load_module(name: str, so: Path):
    """Imports the compiled cffi module at so under name."""
    spec = importlib.util.spec_from_file_location(name, so)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the compiled module {so}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
