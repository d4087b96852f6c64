"""The wheel: it carries lib/metacell (the C sources the emulator compiles), the scenes and the console scripts,
and the emulator installed from it runs outside the repository (or says clearly what is missing)."""

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = {"metacell-emulator", "metacell-logger", "metacell-command", "metacell-experiment", "metacell-flash"}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built by `pip wheel --no-deps --no-build-isolation` from a copy of the checkout's files (so the
    build's own build/ and egg-info never land in the working tree)."""
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the file list comes from git")
    tmp = tmp_path_factory.mktemp("wheel")
    files = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "-co", "--exclude-standard", "-z"], capture_output=True, check=True
    ).stdout.split(b"\0")
    src = tmp / "src"
    for f in filter(None, (x.decode() for x in files)):
        p = ROOT / f
        if p.is_file():
            (src / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(p, src / f)
    r = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp / "dist"), "."],
        cwd=src,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    (whl,) = (tmp / "dist").glob("metamaterial_rig-*.whl")
    return whl


def test_wheel_carries_the_firmware_sources_scenes_and_scripts(wheel):
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        lib = ROOT / "lib" / "metacell"
        want = sorted(p for pat in ("*.c", "*.h") for p in (lib / "src").rglob(pat))
        assert len(want) >= 20
        for p in want + [lib / "library.json"]:
            name = "host_emulator/_lib/metacell/" + p.relative_to(lib).as_posix()
            assert name in names, name
            assert z.read(name) == p.read_bytes(), name  # the very bytes of the checkout
        for p in sorted((ROOT / "host_emulator" / "scenes").glob("*.toml")) + sorted(
            (ROOT / "host_emulator" / "csrc").glob("*.[ch]")
        ):
            assert p.relative_to(ROOT).as_posix() in names, p
        ep = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
        scripts = {ln.split("=")[0].strip() for ln in z.read(ep).decode().splitlines() if "=" in ln}
        assert SCRIPTS <= scripts
        assert not any(n.startswith(("tests/", "lib/", "build/", "out/")) for n in names)
        if (ROOT / "protocol" / "__init__.py").exists():  # protocol becomes a package: its database goes along
            assert "protocol/metacell.dbc" in names
        for pkg in ("metacell_common", "metacell_common/target", "protocol"):  # the layers below the emulator
            for p in sorted((ROOT / pkg).glob("*.py")):
                assert p.relative_to(ROOT).as_posix() in names, p


@pytest.mark.slow
def test_emulator_from_the_installed_wheel_runs_outside_the_repository(wheel, tmp_path):
    """pip install of the wheel (no deps: this environment has them), then the console script, from a directory
    outside the checkout: it compiles the packaged lib/metacell into its own cache and runs the default scene."""
    site = tmp_path / "site"
    r = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site), str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    env = {k: v for k, v in os.environ.items() if k not in ("MC_BUILD_DIR", "PYTHONPATH")}
    env |= {"PYTHONPATH": str(site), "XDG_CACHE_HOME": str(tmp_path / "cache"), "MPLBACKEND": "Agg"}
    where = subprocess.run(
        [sys.executable, "-c", "import host_emulator.firmware as f; print(f.__file__); print(f.IN_CHECKOUT)"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    ).stdout.split()
    assert where == [str(site / "host_emulator" / "firmware.py"), "False"]  # the installed copy, not the checkout
    out = tmp_path / "x"
    cmd = [str(site / "bin" / "metacell-emulator"), "run", "default", "--set", "t_end_s=1", "--out", str(out)]
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    s = json.loads((out / "summary.json").read_text())
    assert s["scene"] == "default" and s["domain_walls"] == 4 and (out / "spacetime.png").stat().st_size > 0
    assert list((tmp_path / "cache" / "metacell-emulator" / "host").iterdir())  # built in the user's cache
    # without the packaged sources: one clear line, exit 3, no traceback
    shutil.rmtree(site / "host_emulator" / "_lib")
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 3 and "firmware sources are not here" in r.stderr and "Traceback" not in r.stderr
