"""Every Unity suite under test/ compiled with gcc against the real Unity 2.6.1 and run; a broken vector must fail it.

The quick companion of tests/firmware/test_pio_build.py (which runs the same suites through `pio test -e native`):
Unity's sources come from the offline PlatformIO tree named by MC_PIO_TREE (libraries/Unity/src) or from a project
build's .pio/libdeps/native/Unity/src; without either the tests are skipped with one line saying so.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.vectors import cheader
from tests.firmware.vectors import primary as pv
from tests.firmware.vectors import regs as rv
from tests.firmware.vectors import slcan as sv

ROOT = Path(__file__).resolve().parents[2]
LIB_SRC = ROOT / "lib" / "metacell" / "src"
SUITES = sorted(p.name for p in (ROOT / "test").glob("test_*") if (p / "test_main.c").is_file())


def _unity_src():
    tree = os.environ.get("MC_PIO_TREE")
    for cand in ([Path(tree) / "libraries" / "Unity" / "src"] if tree else []) + [
        ROOT / ".pio" / "libdeps" / "native" / "Unity" / "src"
    ]:
        if (cand / "unity.c").is_file():
            return cand
    return None


UNITY = _unity_src()
pytestmark = pytest.mark.skipif(
    UNITY is None or shutil.which("cc") is None,
    reason="no real Unity (set MC_PIO_TREE, or run `pio test -e native` once) or no host C compiler",
)


def build_and_run(tmp_path: Path, suite: str, headers: Path, golden: str | None = None):
    """Compile test/<suite>/test_main.c with the generated bus-vector headers in `headers` and run it.
    golden: replacement text of the golden-vector suite's header (the suite is copied beside it)."""
    main = ROOT / "test" / suite / "test_main.c"
    if golden is not None:
        tdir = tmp_path / "test" / suite
        tdir.mkdir(parents=True)
        (tmp_path / "metacell_tools" / "fwcheck").mkdir(parents=True)
        (tmp_path / "metacell_tools" / "fwcheck" / "csrc").symlink_to(ROOT / "metacell_tools" / "fwcheck" / "csrc")
        (tdir / "test_main.c").write_text(main.read_text())
        (tdir / "golden_vectors.h").write_text(golden)
        main = tdir / "test_main.c"
    exe = tmp_path / f"{suite}.bin"
    flags = ["-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", f"-I{UNITY}", f"-I{LIB_SRC}", f"-I{headers}"]
    srcs = [str(main), str(UNITY / "unity.c"), *map(str, sorted(LIB_SRC.rglob("*.c")))]
    cc = subprocess.run(["cc", *flags, *srcs, "-o", str(exe)], capture_output=True, text=True)
    assert cc.returncode == 0, cc.stderr[-3000:]
    return subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def headers(tmp_path_factory):
    out = tmp_path_factory.mktemp("vectors")
    cheader.write_headers(out)
    return out


def test_every_suite_is_here():
    assert SUITES == ["test_native_primary", "test_native_regs", "test_native_slcan", "test_native_vectors"]


@pytest.mark.parametrize("suite", SUITES)
def test_suite_passes(tmp_path, headers, suite):
    p = build_and_run(tmp_path, suite, headers)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr
    assert " 0 Failures" in p.stdout and "FAIL" not in p.stdout.replace("0 Failures", "")


# one vector of each bus suite broken at its source (the Python vector), and the failure Unity must report
BROKEN = {
    "test_native_regs": (lambda: rv.CASES[0], "params", lambda v: (v[0], v[1] + 1, *v[2:]), "test_accepted_writes"),
    "test_native_slcan": (lambda: sv.LINE_CASES[0], "reply", lambda v: "z\r", "test_malformed_lines_rejected"),
    "test_native_primary": (
        lambda: pv.COMMAND_CASES[0],
        "frames",
        lambda v: [(v[0][0], v[0][1][:2] + bytes([pv.R["RANGE"]]) + v[0][1][3:])],
        "test_commands",
    ),
}


@pytest.mark.parametrize("suite", sorted(BROKEN))
def test_a_broken_vector_fails_its_suite(tmp_path, monkeypatch, suite):
    case, key, spoil, failing = BROKEN[suite]
    v = case()
    monkeypatch.setitem(v, key, spoil(v[key]))
    out = tmp_path / "vectors"
    cheader.write_headers(out)
    p = build_and_run(tmp_path, suite, out)
    assert p.returncode != 0
    assert f"{failing}:FAIL" in p.stdout and "1 Failures" in p.stdout, p.stdout[-2000:]


def test_a_wrong_golden_value_fails_in_its_family(tmp_path, headers):
    from metacell_tools.fwcheck import golden

    text = golden.HEADER_PATH.read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("static const uint32_t golden_fam_fnv"))
    vals = line.split("{")[1].split("}")[0].split(", ")
    vals[3] = f"{int(vals[3].rstrip('u'), 16) ^ 1:#010x}u"  # the drive family
    bad = line.split("{")[0] + "{" + ", ".join(vals) + "};"
    p = build_and_run(tmp_path, "test_native_vectors", headers, golden=text.replace(line, bad))
    assert p.returncode != 0
    assert "test_drive_vectors:FAIL" in p.stdout and "1 Failures" in p.stdout
