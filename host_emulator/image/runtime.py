"""Build and load the image tier's compiled runtime: the SAMD21 board models and world (image/csrc), the plant
(host_emulator/csrc) and the firmware library, linked with Unicorn's static library, loaded through cffi.

The register table and a host-compilable view of the vendor's device headers are generated into the build
directory from the headers of the PlatformIO tree that builds the images (regtable.py); where the tree is absent
(the register-level harness needs no images), from the table's committed snapshot and the vendor macros it keeps.
The cycle model's decode table (costtable.py, for code not loaded from an ELF) is generated there too.
The build is cached by a hash of every source, the generated files and the flags. A scratch copy of csrc/ (the
test that follows docs/image-tier.md's recipe for a new model) builds with `load(csrc=..., build_dir=...)`.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

from .. import firmware
from . import ImageTierUnavailable, build, costtable, regsnapshot, regtable

IMAGE_CSRC = Path(__file__).resolve().parent / "csrc"
RUNTIME_HEADERS = ("sam_regtab.h", "sam_api.h")  # the cffi-visible part of the runtime


class RuntimeBuildError(ImageTierUnavailable):
    """The runtime cannot be built (Unicorn, the device headers or a C compiler missing)."""


UNICORN_ENV = "MC_UNICORN"  # which Unicorn the runtime links: "patched" (the default) or "stock"


def unicorn_paths() -> tuple[Path, Path]:
    """(include dir, static library) of the Unicorn the runtime links (RuntimeBuildError).

    MC_UNICORN=patched (the default): the pinned release with this project's patches (ucbuild: `make setup` builds
    it), the same results faster. MC_UNICORN=stock: the released wheel's library, as published."""
    which = os.environ.get(UNICORN_ENV) or "patched"
    if which == "patched":
        from host_emulator.image import ucbuild

        got = ucbuild.installed()
        if got is None:
            raise RuntimeBuildError(
                f"the image tier's Unicorn ({ucbuild.VERSION} with the project's patches) is not built: run `make "
                f"setup` or `python -m host_emulator.image.ucbuild` (or {UNICORN_ENV}=stock for the released wheel)"
            )
        return got
    if which != "stock":
        raise RuntimeBuildError(f"{UNICORN_ENV}={which!r}: expected 'patched' or 'stock'")
    spec = importlib.util.find_spec("unicorn")
    if spec is None or not spec.origin:
        raise RuntimeBuildError(
            "the image tier needs the unicorn package (Python); install the project's dependencies "
            "(pip install -e . in the repository, or make setup)"
        )
    root = Path(spec.origin).resolve().parent
    inc, lib = root / "include", root / "lib" / "libunicorn.a"
    if not (inc / "unicorn" / "unicorn.h").is_file() or not lib.is_file():
        raise RuntimeBuildError(f"the unicorn package at {root} lacks include/unicorn/unicorn.h or lib/libunicorn.a")
    return inc, lib


_digests: dict[tuple[str, int, int], str] = {}


def _file_digest(path: Path) -> str:
    """sha256 of a file, remembered by (path, size, mtime): the whole library enters the runtime's key."""
    st = path.stat()
    k = (str(path), st.st_size, st.st_mtime_ns)
    if k not in _digests:
        _digests[k] = build.sha256_file(path)
    return _digests[k]


_lock = threading.Lock()
_cache: dict[str, tuple[Any, Any]] = {}


def load(
    pio_tree: str | None = None,
    *,
    csrc: Path | None = None,
    table: regtable.Table | None = None,
    build_dir: Path | None = None,
) -> tuple[Any, Any]:
    """(ffi, lib) of the runtime, built on first use (RuntimeBuildError, regtable.RegTableError).

    By default from IMAGE_CSRC against the register table of `pio_tree` (or its snapshot), built under build/image/.
    `csrc` builds from another copy of the sources, `table` against another table, and `build_dir` places the
    build elsewhere; a copy's build has its own key (the sources' directory is hashed), so it never replaces the
    runtime of IMAGE_CSRC."""
    inc, libuc = unicorn_paths()
    csrc = IMAGE_CSRC if csrc is None else Path(csrc).resolve()
    table = regsnapshot.load_or_snapshot(pio_tree) if table is None else table
    gen_c = regtable.emit_c(table)
    gen_h = regtable.emit_vendor_h(table)
    gen_cost = costtable.emit_c()
    fw_srcs = firmware._sources()
    fw_hdrs = firmware._headers()
    img_srcs = sorted(csrc.glob("*.c"))
    img_hdrs = sorted(csrc.glob("*.h"))
    h = hashlib.sha256()
    if csrc != IMAGE_CSRC:
        h.update(str(csrc).encode())
    for p in fw_srcs + fw_hdrs + img_srcs + img_hdrs:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(gen_c.encode())
    h.update(gen_h.encode())
    h.update(gen_cost.encode())
    h.update(_file_digest(libuc).encode())
    h.update(" ".join(firmware.CFLAGS + firmware.LDFLAGS).encode())
    h.update(sys.version.encode())
    key = h.hexdigest()[:16]
    with _lock:
        if key not in _cache:
            atmel = None if table.vendor_macros is not None else Path(table.source)
            outdir = (build_dir or firmware.BUILD_DIR.parent / "image") / key
            mod = _build(key, outdir, csrc, fw_srcs, fw_hdrs, img_srcs, gen_c, gen_h, gen_cost, atmel, inc, libuc)
            _cache[key] = (mod.ffi, mod.lib)
        return _cache[key]


def _build(
    key,
    outdir: Path,
    csrc: Path,
    fw_srcs,
    fw_hdrs,
    img_srcs,
    gen_c,
    gen_h,
    gen_cost,
    atmel_inc: Path | None,
    uc_inc: Path,
    libuc: Path,
):
    name = f"_mcimg_{key}"
    so = next(outdir.glob(f"{name}*.so"), None) if outdir.exists() else None
    if so is None:
        import cffi

        gen_dir = outdir / "gen"
        gen_dir.mkdir(parents=True, exist_ok=True)
        (gen_dir / "sam_regtab_gen.c").write_text(gen_c)
        (gen_dir / "sam_vendor_gen.h").write_text(gen_h)
        (gen_dir / "sam_cost_gen.h").write_text(gen_cost)
        srcs = [*fw_srcs, *img_srcs, gen_dir / "sam_regtab_gen.c"]
        incs = [firmware.LIB_SRC, firmware.HOST_CSRC, csrc, gen_dir]
        # the vendor's and Unicorn's headers are system headers: -pedantic judges only our sources
        sys_incs = [*([f"-isystem{atmel_inc}"] if atmel_inc else []), f"-isystem{uc_inc}"]
        firmware.check_pedantic([s for s in img_srcs], incs, tuple(sys_incs))
        ffi = cffi.FFI()
        headers = [*fw_hdrs, *(csrc / h for h in RUNTIME_HEADERS)]
        ffi.cdef(firmware.cdef_source(headers))
        ffi.set_source(
            name,
            "".join(f'#include "{h}"\n' for h in headers),
            sources=[str(s) for s in srcs],
            include_dirs=[str(d) for d in incs],
            extra_compile_args=[*firmware.CFLAGS, *sys_incs, "-pthread"],
            extra_link_args=[*firmware.LDFLAGS, str(libuc), "-pthread", "-lm"],
        )
        tmp = Path(tempfile.mkdtemp(prefix="mcimg-", dir=outdir.parent))
        try:
            try:
                built = Path(ffi.compile(tmpdir=str(tmp), verbose=False))
            except Exception as e:  # cffi raises VerificationError/CompileError/LinkError
                raise RuntimeBuildError(f"compiling the image tier's runtime failed ({type(e).__name__}: {e})") from e
            so = firmware.place_module(built, outdir)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return firmware.load_module(name, so)
