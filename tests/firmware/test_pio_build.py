"""The real firmware build: `pio run -e cell`, `pio run -e primary` (post-link fwcheck lint on) and `pio test -e native`
under Seeed's Arduino SAMD core and the real Unity, offline.

Runs when PlatformIO can build without the registry: a pre-installed tree named by MC_PIO_TREE (run through its
use.sh), or the user's own ~/.platformio holding the atmelsam and native platforms. Otherwise it is skipped with
one line saying why. Any build or test error fails it.
"""

import fcntl
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PIO = Path(sys.executable).with_name("pio")
# budgets of the linked images (bytes); measured 20,904 / 3,508 (cell) and 19,576 / 8,292 (primary), GCC 12.2.1
BUDGET = {"cell": {"Flash": 32 * 1024, "RAM": 8 * 1024}, "primary": {"Flash": 32 * 1024, "RAM": 12 * 1024}}


def _how():
    tree = os.environ.get("MC_PIO_TREE")
    if not PIO.exists():
        return None, f"pio not installed in {PIO.parent} (pip install platformio==6.2.0)"
    if tree:
        use = Path(tree) / "use.sh"
        if not use.is_file():
            return None, f"MC_PIO_TREE={tree} has no use.sh"
        return ["bash", str(use), str(Path(tree).resolve()), str(ROOT)], None
    home = Path(os.environ.get("PLATFORMIO_CORE_DIR", Path.home() / ".platformio"))
    if (home / "platforms" / "atmelsam").is_dir() and (home / "platforms" / "native").is_dir():
        return None, "own"
    return None, "no offline PlatformIO tree: set MC_PIO_TREE or install the atmelsam and native platforms"


def _build(tmp_path_factory):
    cmd, why = _how()
    env = dict(
        os.environ,
        PIO=str(PIO),
        PATH=f"{PIO.parent}{os.pathsep}{os.environ.get('PATH', '')}",
        PIO_OFFLINE_WORK=str(tmp_path_factory.mktemp("pio")),
    )
    if why == "own":
        logs = []
        for args in (["run", "-e", "cell"], ["run", "-e", "primary"], ["test", "-e", "native"]):
            r = subprocess.run([str(PIO), *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
            logs.append(r.stdout + r.stderr)
            assert r.returncode == 0, logs[-1][-4000:]
        return "\n".join(logs)
    if cmd is None:
        pytest.skip(f"real PlatformIO build skipped: {why}")
    shutil.rmtree(ROOT / ".pio", ignore_errors=True)
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=1200)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-6000:]
    return out


@pytest.fixture(scope="module")
def build_log(tmp_path_factory):
    """The log of one real build, shared by the xdist workers: the first builds under a lock, the others read
    its log (two builds into the same .pio would delete each other's objects)."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # this run's, never an older run's
    log, failed = shared / "pio_build.log", shared / "pio_build.failed"
    with open(shared / "pio_build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if failed.exists():
            pytest.fail(failed.read_text())
        if not log.exists():
            try:
                log.write_text(_build(tmp_path_factory))
            except pytest.skip.Exception:
                raise
            except BaseException as e:
                failed.write_text(str(e)[-6000:])
                raise
        return log.read_text()


def _sections(log):
    """Per environment: {'Flash': bytes, 'RAM': bytes} from PlatformIO's size report, in build order."""
    return [(m.group(1), int(m.group(2))) for m in re.finditer(r"^(RAM|Flash):.*used (\d+) bytes", log, re.M)]


def test_both_images_build_and_fit_their_budgets(build_log):
    sizes = _sections(build_log)
    assert len(sizes) == 4, sizes  # RAM and Flash of cell, then of primary
    for role, chunk in (("cell", sizes[:2]), ("primary", sizes[2:])):
        for kind, used in chunk:
            assert 0 < used <= BUDGET[role][kind], (role, kind, used)


def test_post_link_lint_ran_on_both_images(build_log):
    assert re.search(r"fwcheck lint \S*cell/firmware\.elf: roots mc_cell_tick", build_log)
    assert re.search(r"fwcheck lint \S*primary/firmware\.elf: roots mc_primary_next", build_log)
    assert "helpers on the control path: none" in build_log
    assert "fwcheck: FAILED" not in build_log and "WARNING `python -m metacell_tools.fwcheck lint`" not in build_log


SUITES = sorted(p.name for p in (ROOT / "test").glob("test_*") if (p / "test_main.c").is_file())


def test_every_unity_suite_passed_under_real_unity(build_log):
    """`pio test -e native` ran every suite under test/ (golden vectors, registers, SLCAN, primary), none failed."""
    assert len(SUITES) >= 4, SUITES
    summary = dict(re.findall(r"^native\s+(test_\S+)\s+(PASSED|FAILED|ERRORED|SKIPPED)\b", build_log, re.M))
    assert summary == {s: "PASSED" for s in SUITES}, summary
    m = re.search(r"(\d+) test cases: (\d+) succeeded", build_log)
    assert m and m.group(1) == m.group(2) and int(m.group(1)) >= 20, build_log[-2000:]
    assert "[FAILED]" not in build_log


def test_cell_image_holds_our_interrupt_handlers(build_log):
    nm = shutil.which("arm-none-eabi-nm")
    assert nm, "arm-none-eabi-nm missing"
    syms = subprocess.run([nm, str(ROOT / ".pio/build/cell/firmware.elf")], capture_output=True, text=True).stdout
    strong = {line.split()[-1] for line in syms.splitlines() if re.match(r"^\S+ T ", line)}
    # the core's weak default would be a 'W' alias of Dummy_Handler: ours must be strong text symbols
    assert "TC3_Handler" in strong


def test_docs_quote_the_measured_image_sizes(build_log):
    """README.md and docs/hardware.md quote the sizes this build measures (cell flash / RAM, primary flash / RAM)."""
    sec = _sections(build_log)
    cell, primary = dict(sec[:2]), dict(sec[2:])
    ram_c, flash_c, ram_p, flash_p = cell["RAM"], cell["Flash"], primary["RAM"], primary["Flash"]
    readme = (ROOT / "README.md").read_text()
    assert f"(cell {flash_c:,} B flash / {ram_c:,} B\nRAM, primary {flash_p:,} / {ram_p:,};" in readme
    hw = (ROOT / "docs" / "hardware.md").read_text()
    assert f"cell {flash_c:,} B flash / {ram_c:,} B RAM, primary {flash_p:,} B / {ram_p:,} B" in hw
