"""Host side of the golden vectors: csrc/mc_vectors.c driving the cffi build of the library.

The generator is compiled into its own small cffi module that does *not* contain
the library: it reaches the library only through a table of function pointers,
filled here with the addresses of the functions in ``metacell_common.firmware.load()`` (host_emulator.firmware).
So the host figures come from the very module every other host test uses.
"""

from __future__ import annotations

import importlib.util
import os
import re
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from metacell_common import firmware
from metacell_common.firmware import check_pedantic

from .armbuild import LIB_SRC, _digest, _publish

CSRC = Path(__file__).resolve().parent / "csrc"
HEADER = CSRC / "mc_vectors.h"
HOST_CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-DMCV_NO_TYPECHECK"]


def _header_ints() -> dict[str, int]:
    vals = {}
    for m in re.finditer(r"^#define\s+(MCV_\w+)\s+(\d+)\s*(?:/\*.*)?$", HEADER.read_text(), re.M):
        vals[m.group(1)] = int(m.group(2))
    return vals


def api_names() -> list[str]:
    """Entry points in table order, parsed from the MCV_API X-macro."""
    text = HEADER.read_text()
    m = re.search(r"#define MCV_API\(X\)(.*?)\n\n", text, re.S)
    if m is None:
        raise ValueError(f"{HEADER}: no MCV_API(X) table")
    return re.findall(r"X\((\w+)\)", m.group(1))


CONST = _header_ints()
WORDS = CONST["MCV_WORDS"]
N_TOTAL = CONST["MCV_N_TOTAL"]
FAMILIES = {1: "reaction", 2: "params", 3: "drive", 4: "quad", 5: "cell"}
# word meanings per family (index 1..15), for mismatch reports
FIELDS = {
    1: "alpha beta g_ab g_sigma g1 g2 astar_q4 | ra rb psi(alpha) psi(beta) rc c1",
    2: "in0 in1 in2 in3 in4 in5 in6 | rc unchanged out0 out1 out2 out3 out4 out5",
    3: "tau dtheta bemf limit_req cfg_rc - - | signed_duty duty dir enable duty_limit duty_max",
    4: "start_pos ab_seq - - - - - | pos errors ab saturated snap.pos snap.errors snap.sat",
    5: "pos_a pos_b err_a err_b sat rc arg | faults out_a out_b torque_a torque_b theta_a theta_b pert^faults<<16",
}


def _cdef() -> str:
    n_fn = len(api_names())
    return f"""
typedef void (*mcv_fn)(void);
typedef struct {{ mcv_fn fn[{n_fn}]; }} mcv_api_t;
typedef struct mcv_sink {{
    uint32_t *data; uint32_t cap_words; uint32_t n_words; uint32_t n_records;
    uint32_t fnv; uint32_t overflow; void (*flush)(struct mcv_sink *s);
    uint32_t fam_fnv[8]; uint32_t fam_count[8];
}} mcv_sink_t;
void mcv_sink_init(mcv_sink_t *s, uint32_t *data, uint32_t cap_words);
uint32_t mcv_run(const mcv_api_t *api, uint32_t seed, mcv_sink_t *sink);
uint32_t mcv_xorshift32(uint32_t *state);
"""


_mod: ModuleType | None = None


def module() -> ModuleType:
    """The compiled generator module (cffi), built on first use and cached by hash."""
    global _mod
    if _mod is not None:
        return _mod
    import cffi

    srcs = [CSRC / "mc_vectors.c", HEADER] + sorted(LIB_SRC.rglob("*.h"))
    key = _digest(srcs, HOST_CFLAGS + [_cdef()])
    name = f"_mcvec_{key}"

    def build(tmp: Path) -> None:
        check_pedantic(  # -pedantic for our source, not cffi's wrapper
            [CSRC / "mc_vectors.c"], [CSRC, LIB_SRC], ("-DMCV_NO_TYPECHECK",)
        )
        ffi = cffi.FFI()
        ffi.cdef(_cdef())
        ffi.set_source(
            name,
            '#include "mc_vectors.h"\n',
            sources=[str(CSRC / "mc_vectors.c")],
            include_dirs=[str(CSRC), str(LIB_SRC)],
            extra_compile_args=HOST_CFLAGS,
        )
        work = tmp / "work"
        built = Path(ffi.compile(tmpdir=str(work), verbose=False))
        os.replace(built, tmp / built.name)

    d = _publish(build, key, "hostvec")
    so = next(d.glob(f"{name}*.so"))
    spec = importlib.util.spec_from_file_location(name, so)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the compiled module {so}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    _mod = mod
    return mod


def xorshift32(state: int) -> int:
    """The shared PRNG step through the C implementation (for tests)."""
    mod = module()
    s = mod.ffi.new("uint32_t *", state)
    return int(mod.lib.mcv_xorshift32(s))


@dataclass
class HostVectors:
    records: np.ndarray  # (N, WORDS) uint32
    fnv: int
    fam_fnv: dict[int, int]  # family -> FNV-1a of its records
    fam_count: dict[int, int]


def host_vectors(seed: int) -> HostVectors:
    fw_ffi, fw_lib = firmware.load()
    mod = module()
    ffi, lib = mod.ffi, mod.lib
    api = ffi.new("mcv_api_t *")
    for i, name in enumerate(api_names()):
        addr = int(fw_ffi.cast("uintptr_t", fw_ffi.addressof(fw_lib, name)))
        api.fn[i] = ffi.cast("mcv_fn", addr)
    buf = np.zeros(N_TOTAL * WORDS, dtype=np.uint32)
    sink = ffi.new("mcv_sink_t *")
    lib.mcv_sink_init(sink, ffi.cast("uint32_t *", ffi.from_buffer(buf)), buf.size)
    n = lib.mcv_run(api, seed & 0xFFFFFFFF, sink)
    if sink.overflow or n != N_TOTAL:
        raise RuntimeError(f"host vector run produced {n} records (overflow={sink.overflow})")
    return HostVectors(
        buf.reshape(-1, WORDS),
        int(sink.fnv),
        {f: int(sink.fam_fnv[f]) for f in FAMILIES},
        {f: int(sink.fam_count[f]) for f in FAMILIES},
    )


def _signed(w: int) -> int:
    return w - (1 << 32) if w >= 1 << 31 else w


def describe_mismatch(i: int, host: np.ndarray, target: np.ndarray) -> str:
    tag = int(host[0])
    fam = tag >> 24
    names = FIELDS.get(fam, "").replace("|", "").split()
    diff = [k for k in range(WORDS) if host[k] != target[k]]
    lines = [
        f"first mismatch: record {i}, family {FAMILIES.get(fam, fam)} "
        f"(sub {(tag >> 16) & 0xFF}, index {tag & 0xFFFF}); differing words {diff}",
        f"  {'word':<14}{'host':>14}{'target':>14}",
    ]
    for k in range(1, WORDS):
        label = names[k - 1] if k - 1 < len(names) else f"w{k}"
        mark = "  <--" if k in diff else ""
        lines.append(f"  {label:<14}{_signed(int(host[k])):>14}{_signed(int(target[k])):>14}{mark}")
    return "\n".join(lines)
