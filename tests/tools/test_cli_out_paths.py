"""Every CLI entry point with an output path checks it before any work: a place no one can write (under /proc, even
as root), a path through a file and a name too long for the file system each end with one line naming the option,
exit 2, no traceback, and nothing run (the commands below would take minutes if they started working)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LONG = "n" * 300  # over NAME_MAX (255) of every common file system

# (id, module, argv before the path, option, argv after, kind: "dir" | "file" | "prefix" | "link")
WALK = [
    ("run", "host_emulator", ["run", "default", "--quiet", "--no-plots", "--set", "t_end_s=3000"], "--out", [], "dir"),
    (
        "run-live",
        "host_emulator",
        ["run", "default", "--quiet", "--no-plots", "--out", "{tmp}/o"],
        "--live-png",
        ["--live", "50"],
        "file",
    ),
    ("dispersion", "host_emulator", ["dispersion"], "--plot", [], "file"),
    ("robustness", "host_emulator", ["robustness", "--seeds", "50"], "--out", [], "dir"),
    ("paper", "host_emulator", ["paper", "--repeats", "50"], "--out", [], "dir"),
    (
        "sweep",
        "host_emulator",
        ["sweep", "default", "--quiet", "--grid", "params.sigma=0.04:0.12:400"],
        "--out",
        [],
        "dir",
    ),
    ("serve", "host_emulator", ["serve", "default", "--duration", "600"], "--link", [], "link"),
    ("animate", "host_emulator", ["animate", "default"], "--out", [], "gif"),
    ("plot", "host_emulator", ["plot", "{rig}"], "--out", [], "dir"),
    ("bench", "host_emulator", ["bench"], "--out", [], "dir"),
    ("sweep-bench-json", "host_emulator.benchmarks.sweep", [], "--json", [], "file"),
    ("sweep-bench-plot", "host_emulator.benchmarks.sweep", [], "--plot", [], "file"),
    ("instructions-json", "host_emulator.benchmarks.instructions", [], "--json", [], "file"),
    (
        "design",
        "host_emulator",
        ["design", "--target", "lambda=10", "--push", "8", "--maxiter", "1000"],
        "--out",
        [],
        "dir",
    ),
    ("design-table", "host_emulator.benchmarks.design_table", [], "--out", [], "dir"),
    ("logger", "metacell_tools.rigtools.logger", ["-c", "/dev/null@115200", "--duration", "600"], "-o", [], "prefix"),
    ("experiment-run", "metacell_tools.experiment", ["run", "default", "-c", "/dev/null@115200"], "--out", [], "dir"),
    ("experiment-rehearse", "metacell_tools.experiment", ["rehearse", "default"], "--out", [], "dir"),
    (
        "experiment-live",
        "metacell_tools.experiment",
        ["run", "default", "-c", "/dev/null@115200", "--out", "{tmp}/o"],
        "--live-png",
        ["--live"],
        "file",
    ),
    ("experiment-compare", "metacell_tools.experiment", ["compare", "{rig}", "{emu}"], "--out", [], "file"),
    ("fwcheck-golden", "metacell_tools.fwcheck", ["golden-header"], "--out", [], "file"),
]
# options that name an output path, as argparse sees them in the sources
OUT_OPTIONS = re.compile(
    r"""add_argument\(\s*(?:"-o",\s*)?"(--out|--plot|--json|--link|--live-png)"(?![^)]*store_true)"""
)
# the entry point (python -m MODULE) of every source file with such an option; the subcommands of
# `python -m host_emulator` live in many files
ENTRY = {
    "host_emulator/cli.py": "host_emulator",
    "host_emulator/workbench/paper.py": "host_emulator",
    "host_emulator/workbench/robustness.py": "host_emulator",
    "host_emulator/workbench/sweep/cli.py": "host_emulator",
    "host_emulator/workbench/animate.py": "host_emulator",
    "host_emulator/workbench/figures.py": "host_emulator",
    "host_emulator/analysis/cli.py": "host_emulator",
    "host_emulator/bus/serve.py": "host_emulator",
    "host_emulator/benchmarks/cli.py": "host_emulator",
    "host_emulator/benchmarks/sweep.py": "host_emulator.benchmarks.sweep",
    "host_emulator/benchmarks/instructions.py": "host_emulator.benchmarks.instructions",
    "host_emulator/workbench/design/cli.py": "host_emulator",
    "host_emulator/benchmarks/design_table.py": "host_emulator.benchmarks.design_table",
    "metacell_tools/rigtools/logger/cli.py": "metacell_tools.rigtools.logger",
    "metacell_tools/experiment/cli.py": "metacell_tools.experiment",
    "metacell_tools/fwcheck/__main__.py": "metacell_tools.fwcheck",
}


def _bad_paths(tmp: Path, kind: str) -> dict[str, str]:
    blocker = tmp / "a-file"
    blocker.write_text("")
    leaf = {"dir": "out", "file": "x.png", "gif": "x.gif", "prefix": "run1", "link": "rig.pty"}[kind]
    if kind == "file":
        leaf = "x.json"
    return {
        "unwritable": f"/proc/1/nope/{leaf}",
        "through-a-file": str(blocker / leaf),
        "over-long": str(tmp / (LONG + ("" if kind in ("dir", "prefix", "link") else Path(leaf).suffix))),
    }


def _summaries(tmp: Path) -> dict[str, str]:
    """Two run directories compare accepts (the same scene), so only --out can fail."""
    dirs = {}
    for name in ("rig", "emu"):
        d = tmp / name
        d.mkdir()
        (d / "summary.json").write_text(
            json.dumps({"scene": "default", "final_alpha_rad": [0.0] * 16, "final_beta_rad": [0.0] * 16})
        )
        dirs[name] = str(d)
    return dirs


@pytest.mark.parametrize("case", ["unwritable", "through-a-file", "over-long"])
@pytest.mark.parametrize("entry", WALK, ids=[w[0] for w in WALK])
def test_every_cli_refuses_an_unwritable_output_path_before_any_work(entry, case, tmp_path):
    _, module, before, opt, after, kind = entry
    path = _bad_paths(tmp_path, kind)[case]
    fill = _summaries(tmp_path) if "{rig}" in before else {}
    fill["tmp"] = str(tmp_path)
    argv = [a.format(**fill) for a in before] + [opt, path] + after
    # generous: a loaded machine may take long to start Python; doing the work would take far longer (minutes)
    r = subprocess.run(
        [sys.executable, "-m", module, *argv], cwd=ROOT, capture_output=True, text=True, timeout=600, stdin=None
    )
    err = r.stderr.strip()
    assert r.returncode == 2, (argv, r.returncode, err[-2000:])
    assert "Traceback" not in err and len(err.splitlines()) == 1, err[-2000:]
    assert opt in err or opt.lstrip("-") in err, err
    assert len(err) < 400, err  # an over-long path is shortened in the message


def test_the_walk_covers_every_output_option():
    """A new --out/--plot/--json/--link/--live-png option in any source file (wherever a later change moves it)
    must be added to WALK."""
    walked = {(m, o) for _, m, _, o, _, _ in WALK}
    found, unknown = set(), []
    for top in ("host_emulator", "metacell_common", "metacell_tools", "protocol"):
        for f in sorted((ROOT / top).rglob("*.py")):
            rel = f.relative_to(ROOT).as_posix()
            opts = OUT_OPTIONS.findall(f.read_text())
            if opts and rel not in ENTRY:
                unknown.append(rel)
            for opt in opts:
                module = ENTRY.get(rel, rel)
                found.add((module, "-o" if opt == "--out" and module.endswith("logger") else opt))
    assert not unknown, f"output options in files with no entry point in ENTRY: {unknown}"
    assert found <= walked, sorted(found - walked)
    assert len(found) >= 10  # the scan itself works (it finds the options the walk covers)
