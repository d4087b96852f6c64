"""The layers hold: `lint-imports` (the contracts in pyproject.toml, run by `make lint`) passes on the tree and fails on
an import planted across a layer (the emulator importing the laptop tools, fwcheck importing the emulator)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LINT = Path(sys.executable).with_name("lint-imports")
PACKAGES = ("host_emulator", "metacell_common", "metacell_tools", "protocol")

pytestmark = pytest.mark.skipif(not LINT.exists(), reason="import-linter is not installed (pip install -e '.[dev]')")


def _lint(tree: Path) -> subprocess.CompletedProcess:
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(tree)}
    return subprocess.run(
        [str(LINT), "--no-cache", "--config", str(tree / "pyproject.toml")],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture
def tree(tmp_path) -> Path:
    """The four packages' Python sources and pyproject.toml, copied (the planted imports never touch the checkout)."""
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            dest = tmp_path / f.relative_to(ROOT)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(f, dest)
    shutil.copy2(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def test_the_contracts_hold_on_the_tree(tree):
    r = _lint(tree)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "4 kept, 0 broken" in r.stdout


@pytest.mark.parametrize(
    "module, planted, broken",
    [
        (
            "host_emulator/physics.py",
            "import metacell_tools",
            ["Layers:", "The emulator never imports the laptop tools"],
        ),
        ("metacell_tools/fwcheck/wcet.py", "import host_emulator", ["only the experiment runner imports the emulator"]),
        ("metacell_common/outpaths.py", "import host_emulator", ["Layers:"]),
        ("host_emulator/controller.py", "from .workbench import plots", ["The run core"]),
    ],
)
def test_a_planted_import_across_a_layer_fails(tree, module, planted, broken):
    f = tree / module
    f.write_text(f.read_text() + f"\n{planted}  # planted\n")
    r = _lint(tree)
    assert r.returncode == 1, r.stdout[-3000:]
    assert module.replace("/", ".").removesuffix(".py") in r.stdout
    for name in broken:
        assert any(
            name in line and line.rstrip().endswith("BROKEN") for line in r.stdout.replace(" \n", " ").splitlines()
        ), (
            name,
            r.stdout[-3000:],
        )
