"""`make bench` and `make test` coexist: mypy gives the same verdict with and without the bench extra installed.

The bench extra's peers (py-pde, jax, diffrax, scikit-sundae) ship their own types; once installed, mypy used to
read them and fail on our calls (py-pde's CartesianGrid bounds). Installing the real extra here would take
minutes and the network, so typed stand-ins of the same import names go on the path instead: every attribute
is an `int`, so any call into them that mypy followed would be an error (`"int" not callable`)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MYPY = Path(sys.executable).with_name("mypy")
BENCH_MODULES = {  # import name -> submodules the code imports
    "pde": [],
    "jax": ["numpy"],
    "diffrax": [],
    "sksundae": ["cvode"],
}
STAND_IN = "def __getattr__(name: str) -> int: ...\n"


def _typed_stand_ins(root: Path) -> None:
    for name, subs in BENCH_MODULES.items():
        pkg = root / name
        pkg.mkdir(parents=True)
        (pkg / "__init__.py").write_text(STAND_IN)
        (pkg / "py.typed").write_text("")
        for s in subs:
            (pkg / f"{s}.py").write_text(STAND_IN)


def _mypy(tmp: Path, extra_path: Path | None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    if extra_path is not None:
        env["PYTHONPATH"] = str(extra_path)
    # own cache: the verdict must not come from the other run's cache (nor race `make lint`'s)
    return subprocess.run(
        [str(MYPY), "--cache-dir", str(tmp / "cache"), "--no-error-summary"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.mark.slow
def test_mypy_verdict_is_the_same_with_the_bench_extra_installed(tmp_path):
    if not MYPY.exists():
        pytest.skip("mypy is not installed in this environment (dev extra)")
    site = tmp_path / "site"
    _typed_stand_ins(site)
    # the stand-ins are visible to mypy: a probe that imports one is an error
    probe = tmp_path / "probe"
    probe.mkdir()
    (probe / "p.py").write_text("import pde\n\npde.PDE({})\n")
    env = {**os.environ, "PYTHONPATH": str(site)}
    r = subprocess.run(
        [str(MYPY), "--cache-dir", str(tmp_path / "pc"), "--config-file", "/dev/null", str(probe / "p.py")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1 and "not callable" in r.stdout, r.stdout + r.stderr
    without = _mypy(tmp_path / "a", None)
    with_extra = _mypy(tmp_path / "b", site)
    assert without.returncode == 0, without.stdout
    assert with_extra.returncode == without.returncode, with_extra.stdout
    assert with_extra.stdout == without.stdout
