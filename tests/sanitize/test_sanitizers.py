"""The C runtimes under AddressSanitizer and UndefinedBehaviorSanitizer, every finding fatal (-fno-sanitize-recover).

One sanitized build (MC_SANITIZE=1: the image tier's runtime, which holds image/csrc, host_emulator/csrc and the
firmware library) runs a set of tests in a Python that preloads the ASan runtime: the boards running their firmware,
out-of-range requests to the C API and the USB descriptor parser, a guest's addresses at the top of the address
space, the NVIC, the host tier's steppers and firmware-in-the-loop, and issue 32's corrupted ELF past Python's
checks. The fuzz harnesses of fuzz/ run with the same sanitizers in tests/fuzz/test_fuzz.py. First, two
controls show that this set-up does report a heap overflow and a shift by 40 from a module Python loads."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CC = os.environ.get("CC", "cc")
FLAGS = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g"]

# what the sanitized run runs (each file's tests under the sanitizers; the image tier's need MC_PIO_TREE's headers
# or the cached images, else they skip as they do in the suite)
SANITIZED_TESTS = [
    "tests/sanitize/sanitized_checks.py",
    "tests/host_emulator/image/test_corrupt_elf.py::test_the_c_loader_refuses_a_segment_whose_end_wraps",
    "tests/host_emulator/image/test_guest_bounds.py",
    "tests/host_emulator/image/peripherals/test_nvic.py",
    "tests/host_emulator/models/test_steppers.py",
    "tests/host_emulator/models/test_dop853.py",
    "tests/host_emulator/models/test_hil.py",
    # (an encoder property test of pure Python: 17 s under the sanitizers for no C)
    "--deselect=tests/host_emulator/models/test_hil.py::test_encoder_tracks_any_angle_sequence",
]


def sanitizer_runtime() -> tuple[str | None, str]:
    """(the ASan runtime to preload, "") when the C compiler builds sanitized code; else (None, why)."""
    if shutil.which(CC) is None:
        return None, f"no C compiler {CC!r}"
    lib = subprocess.run([CC, "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    if not lib or not os.path.isabs(lib) or not os.path.exists(lib):
        return None, f"{CC} has no ASan runtime (libasan.so; Debian: apt-get install libasan8 libubsan1)"
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "t.c"
        src.write_text("int main(void) { return 0; }\n")
        r = subprocess.run([CC, *FLAGS, str(src), "-o", str(Path(tmp) / "t")], capture_output=True, text=True)
        if r.returncode != 0:
            return None, f"{CC} cannot build with {' '.join(FLAGS[:2])}: {r.stderr.strip()[:200]}"
    return lib, ""


@pytest.fixture(scope="module")
def asan_lib() -> str:
    lib, why = sanitizer_runtime()
    if lib is None:
        pytest.skip(f"sanitizer job skipped: {why}")
    return lib


def sanitized_env(asan_lib: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "COV_"))}
    env.update(
        MC_SANITIZE="1",
        LD_PRELOAD=asan_lib,
        # Python's own allocations are never freed at exit: no leak report; every finding ends the process
        ASAN_OPTIONS="detect_leaks=0:halt_on_error=1:abort_on_error=0:exitcode=86",
        UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:exitcode=87",
        PYTHONPATH=str(ROOT),
    )
    return env


CONTROL = """
#include <stdlib.h>
#include <stdint.h>
int overflow(int size, int at) { char *p = malloc((size_t)size); p[at] = 1; int r = p[0]; free(p); return r; }
uint32_t shift(int n) { return 1u << n; }
"""


@pytest.mark.parametrize(
    "call, report",
    [("overflow(16, 16)", "AddressSanitizer: heap-buffer-overflow"), ("shift(40)", "shift exponent 40")],
    ids=["asan", "ubsan"],
)
def test_the_set_up_reports_a_fault_in_a_module_python_loads(asan_lib, tmp_path, call, report):
    src = tmp_path / "control.c"
    src.write_text(CONTROL)
    so = tmp_path / "control.so"
    subprocess.run([CC, "-shared", "-fPIC", "-O1", *FLAGS, str(src), "-o", str(so)], check=True)
    fn, arg = call.rstrip(")").split("(")
    prog = textwrap.dedent(f"""
        import ctypes
        lib = ctypes.CDLL({str(so)!r})
        lib.{fn}({arg})
        print("survived")
    """)
    r = subprocess.run([sys.executable, "-c", prog], env=sanitized_env(asan_lib), capture_output=True, text=True)
    assert r.returncode in (86, 87) and report in r.stderr and "survived" not in r.stdout, (r.returncode, r.stderr)
    ok = subprocess.run(  # and in range, nothing is reported
        [sys.executable, "-c", prog.replace(f"({arg})", "(16, 3)" if fn == "overflow" else "(3)")],
        env=sanitized_env(asan_lib),
        capture_output=True,
        text=True,
    )
    assert ok.returncode == 0 and "survived" in ok.stdout, ok.stderr


@pytest.mark.slow
def test_the_c_runtimes_under_asan_and_ubsan(asan_lib):
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "tests.sanitize.plugin", "-x"]
        + SANITIZED_TESTS,
        cwd=ROOT,
        env=sanitized_env(asan_lib),
        capture_output=True,
        text=True,
        timeout=1800,
    )
    out = r.stdout + r.stderr
    found = [line for line in out.splitlines() if "Sanitizer" in line or "runtime error:" in line]
    assert r.returncode == 0 and not found, f"exit {r.returncode}\n" + "\n".join(found[:20]) + "\n" + out[-6000:]
    assert " passed" in r.stdout and " failed" not in r.stdout
