"""libFuzzer (clang, ASan + UBSan) on the SLCAN link and the cell register handler, for a bounded time,
seeded from fuzz/corpus/; the harnesses and the library build warning-free (-Wall -Wextra -pedantic, -Werror).
Atheris (libFuzzer for Python) on the image tier's ELF reader and the scene parser, the same way."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SECONDS = int(os.environ.get("MC_FUZZ_SECONDS", "20"))
# as fuzz/run.sh builds them: sanitizers on, every warning an error
CFLAGS = ["-g", "-O1", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"]
CFLAGS += ["-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=undefined"]


@pytest.mark.slow
@pytest.mark.parametrize("harness", ["slcan", "regs"])
def test_fuzz_harness(harness, tmp_path):
    clang = shutil.which("clang")
    assert clang, "clang with libFuzzer is required (tools/setup.sh installs it)"
    srcs = sorted(str(p) for p in (ROOT / "lib" / "metacell" / "src").rglob("*.c"))
    exe = tmp_path / f"fuzz_{harness}"
    inc = f"-I{ROOT / 'lib' / 'metacell' / 'src'}"
    subprocess.run([clang, *CFLAGS, inc, str(ROOT / "fuzz" / f"fuzz_{harness}.c"), *srcs, "-o", str(exe)], check=True)
    corpus = ROOT / "fuzz" / "corpus" / harness
    assert len(list(corpus.iterdir())) > 5
    new = tmp_path / "new"
    new.mkdir()
    r = subprocess.run(
        [
            str(exe),
            f"-max_total_time={SECONDS}",
            "-timeout=5",
            "-rss_limit_mb=2048",
            f"-artifact_prefix={tmp_path}/",
            str(new),
            str(corpus),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    crashes = list(tmp_path.glob("crash-*")) + list(tmp_path.glob("timeout-*")) + list(tmp_path.glob("leak-*"))
    assert r.returncode == 0 and not crashes, r.stderr[-3000:]
    assert "Done" in r.stderr  # ran to the time limit


# Atheris (libFuzzer for Python) targets beside the C harnesses: the image tier's ELF reader and the scene parser
PY_SECONDS = int(os.environ.get("MC_FUZZ_PY_SECONDS", "10"))


@pytest.mark.slow
@pytest.mark.parametrize("target", ["elf", "scene"])
def test_atheris_target(target, tmp_path):
    import importlib.util

    assert importlib.util.find_spec("atheris"), "atheris is required (the dev extras install it)"
    corpus = ROOT / "fuzz" / "corpus" / target
    assert len(list(corpus.iterdir())) >= 2
    new = tmp_path / "new"
    new.mkdir()
    r = subprocess.run(
        [
            sys.executable,
            str(ROOT / "fuzz" / f"fuzz_{target}.py"),
            f"-max_total_time={PY_SECONDS}",
            "-timeout=10",
            "-rss_limit_mb=2048",
            f"-artifact_prefix={tmp_path}/",
            str(new),
            str(corpus),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    crashes = list(tmp_path.glob("crash-*")) + list(tmp_path.glob("timeout-*")) + list(tmp_path.glob("oom-*"))
    assert r.returncode == 0 and not crashes, r.stderr[-3000:]
    assert "Done" in r.stderr  # ran to the time limit
