"""Docs that stay true: the figures in README.md and docs/ that a fast command reproduces (the demo's printout, the
linear theory's table, oscillation periods, code size, instruction counts, bus rates, the paper's count, lint
paths) are compared with what that command prints today. Machine-dependent times are not compared: the docs
name their command and machine beside them."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def _num(text: str) -> float:
    return float(text.replace(",", ""))


def test_readme_demo_printout_is_what_make_demo_prints(tmp_path):
    """Every line of the README's `make demo` block but the first (wall time) is the run's own printout."""
    block = re.search(r"`make demo` prints a summary and where the plots\nare:\n\n((?:    .*\n)+)", README)
    assert block, "README: the make demo block moved"
    quoted = [ln[4:] for ln in block.group(1).splitlines()]
    out = tmp_path / "out" / "default"
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "run", "default", "--out", str(out), "--quiet"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    printed = r.stdout.replace(str(out), "out/default").splitlines()
    assert re.fullmatch(r"scene default \(hil\): 10 s simulated in [\d.]+ s wall \(\d+x real time\)", quoted[0])
    assert printed[1:] == quoted[1:]


def test_the_linear_theory_table_of_analysis_md():
    """Every row of docs/analysis.md's table, recomputed with `dispersion` at the table k."""
    from host_emulator.analysis.stability import dispersion, format_set
    from host_emulator.params import Params

    text = (ROOT / "docs" / "analysis.md").read_text()
    rows = re.findall(r"^\| (\d+/125) \| (\d+) \| (lattice|continuum) \| (no|yes|no / yes) \| (.+?) \|$", text, re.M)
    assert len(rows) >= 14
    for sig, eta, model, inertia, rest in rows:
        cols = [c.strip() for c in rest.split("|")]
        regime, fastest, growth, uset, uniform, chain = cols
        n, d = map(int, sig.split("/"))
        for inert in [x == "yes" for x in inertia.split(" / ")]:
            p = Params(sigma=n / d, band_scale=0.5, eta_scale=float(eta))
            res = dispersion(p, inertia=inert, discrete=model == "lattice", n_cells=16)
            row = f"{sig} eta x{eta} {model} inertia={inert}"
            assert regime.strip("*") == res["regime"], row
            assert format_set(res["unstable_set_cells"]) == uset, row
            assert f"{res['fastest_growth_per_s']:+.2f}" == growth, row
            if res["fastest_lambda_cells"]:
                assert fastest == f"{res['fastest_lambda_cells']:.3f}", row
            else:
                assert fastest == f"inf (uniform), period {res['oscillation_period_s']:.3f} s", row
            um = [f"{res['uniform_mode_growth_per_s']:+.1f}"]
            if res["uniform_mode_period_s"]:
                um.append(f"{res['uniform_mode_period_s']:.3f}")
            assert ", ".join(um) in uniform, row


def test_the_fourteen_over_125_periods_in_the_readme():
    """README: the lattice with the torque limit and the hil model with back-EMF compensation oscillate at the
    quoted periods; the shipped hil scene decays to rest."""
    from host_emulator.analysis.observables import observables
    from host_emulator.controller import run_scene
    from host_emulator.scene import load_scene

    m = re.search(
        r"the ideal lattice with the actuators' torque limit, ([\d.]+) s.*?back-EMF compensation,\s+([\d.]+) s",
        README,
        re.S,
    )
    assert m, "README: the 14/125 sentence moved"
    for sets, quoted in ((["model=lattice"], m.group(1)), (["params.bemf_comp=true"], m.group(2))):
        res = run_scene(load_scene("exp3_single_sigma14", sets), progress=False)
        per = observables(res.t, res.alpha, res.beta)["oscillation_period_s"]
        assert f"{per:.4g}" == quoted, (sets, per)
    res = run_scene(load_scene("exp3_single_sigma14"), progress=False)
    assert observables(res.t, res.alpha, res.beta)["oscillation_period_s"] is None


def test_lint_paths_in_the_readme_are_the_makefiles():
    make = re.search(r"^LINT_PATHS := (.+)$", (ROOT / "Makefile").read_text(), re.M).group(1).split()
    m = re.search(r"`ruff format --check` \(both over ([^)]+)\)", README)
    named = re.split(r",\s*|\s+and\s+", m.group(1).replace("\n", " "))
    assert sorted(x.strip() for x in named if x.strip()) == sorted(make)


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc missing")
def test_code_size_quoted_in_readme_and_firmware_proof():
    from metacell_tools.fwcheck import armbuild

    rows = armbuild.code_size(armbuild.library_objects())
    total = next(r.text for r in rows if r.name == "total")
    m = re.search(r"code size \(`\.text`, all objects.*?\| ([\d,]+) bytes", README)
    assert _num(m.group(1)) == total
    fp = (ROOT / "docs" / "firmware-proof.md").read_text()
    assert f"total {total}" in fp


@pytest.mark.skipif(
    shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
    reason="arm-none-eabi-gcc / qemu-system-arm missing",
)
def test_instruction_counts_quoted_in_readme_and_firmware_proof():
    from metacell_tools.fwcheck import qemu

    s = qemu.tick_stats()
    base = sorted(s.select(**qemu.BUDGET_CASE))
    bemf = sorted(s.select(**qemu.BUDGET_BEMF_CASE))

    def med(v):
        return v[len(v) // 2]

    assert f"**median {med(base)}, max {base[-1]}** (budget {qemu.BUDGET})" in README
    assert f"median {med(bemf)}, max {bemf[-1]} (budget {qemu.BUDGET_BEMF})" in README
    quad = sorted(s.quad_update)
    assert f"| {min(quad)}-{quad[-1]} / {max(s.snapshot)} instructions |" in README
    fp = (ROOT / "docs" / "firmware-proof.md").read_text()
    assert f"| **{med(base)}** | **{base[-1]}** |" in fp and f"| **{med(bemf)}** | **{bemf[-1]}** |" in fp


def test_bus_rates_in_the_readme():
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator.benchmarks.bus"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr
    limit = re.search(
        r"I2C 400 kHz.*?full-lattice rate :\s+([\d.]+) Hz\s+emulated primary schedule\s+:\s+([\d.]+) Hz\s+= ([\d.]+) %",
        r.stdout,
        re.S,
    )
    lim, got, pct = (float(x) for x in limit.groups())
    assert (
        f"allowed by a 400 kHz bus is {lim:.1f} Hz and the primary's schedule\nreaches {got:.1f} Hz ({pct:.1f} %)"
        in README
    )


def test_the_paper_count_in_the_readme(tmp_path):
    """README's 'N of N agree' is the paper command's count (one repeat per Fig. 3 panel: the count of items does
    not depend on the repeats)."""
    from host_emulator.workbench.paper import build

    doc = build(tmp_path, repeats=1)
    m = re.search(r"item by item \((\d+) of (\d+) agree\)", README)
    assert (int(m.group(1)), int(m.group(2))) == (doc["agree"], doc["total"])
    bs = (ROOT / "docs" / "band-stiffness.md").read_text()
    assert (
        f"**{doc['agree']} of {doc['total']}\nitems agree**" in bs
        or f"**{doc['agree']} of {doc['total']} items agree**" in bs
    )


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind missing")
def test_instructions_per_cell_tick_quoted_in_readme_and_docs():
    """The README's and docs' instruction count of the hil default is what the instruction script counts today
    (callgrind: it does not depend on the machine's speed or load, only on the compiled code)."""
    from host_emulator.benchmarks.instructions import measure

    got = measure().per_cell_tick
    # the quoted figure is a whole number; the whole-process count moves by a few tenths between runs (the Python
    # and libc share, e.g. 358.50 and 358.68 of the same build), so a figure within one instruction is today's
    pages = {
        "README.md": (README, r"\*\*(\d+) x86 instructions per cell and control tick\*\*"),
        "docs/accuracy.md": ((ROOT / "docs" / "accuracy.md").read_text(), r"-> (\d+) instructions per cell-tick\*\*"),
        "docs/emulator.md": (
            (ROOT / "docs" / "emulator.md").read_text(),
            r"\*\*(\d+) x86 instructions per cell and control tick\*\*",
        ),
    }
    for page, (text, pattern) in pages.items():
        quoted = [int(x) for x in re.findall(pattern, text)]
        assert quoted, f"{page}: the instruction figure moved"
        assert abs(quoted[-1] - got) < 1.0, (page, quoted[-1], got)


def test_design_page_lambda_10_row_is_what_design_prints(tmp_path):
    """docs/design.md's first worked example: the fractions and the parameters are what `design` prints today."""
    page = (ROOT / "docs" / "design.md").read_text()
    row = re.search(
        r"\| `design --target lambda=10 --push 8` \| (\d+) % of 20 / (\d+) % of 12 \| .*? \| (.*?) \|", page
    )
    assert row, "docs/design.md: the lambda=10 row moved"
    r = subprocess.run(
        [sys.executable, "-m", "host_emulator", "design", "--target", "lambda=10", "--push", "8", "--quiet"]
        + ["--out", str(tmp_path / "d")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    m = re.search(r"lands in (\d+) % of 20 noise seeds and (\d+) % of 12 pushes", r.stdout)
    assert m and m.groups() == row.groups()[:2], (r.stdout, row.groups())
    printed = {k: float(v) for k, v in re.findall(r"^  (\w+): ([-\d.e]+)$", r.stdout, re.M)}
    quoted = {k: float(v) for k, v in re.findall(r"(\w+) ([-\d.]+)", row.group(3))}
    assert quoted and all(abs(printed[k] - v) <= 5e-5 for k, v in quoted.items()), (printed, quoted)


def test_design_page_band_scan_is_what_the_scan_finds():
    """docs/design.md's "linear band": the number of laws scanned and the largest fastest mode are band_scan's."""
    from host_emulator.benchmarks.design_table import band_scan

    page = (ROOT / "docs" / "design.md").read_text()
    m = re.search(
        r"at most m = (\d+) \(a cosine wavelength of\s+([\d.]+)\s+cells\): over a grid of ([\d,]+) laws", page
    )
    assert m, "docs/design.md: the band-scan sentence moved"
    res = band_scan()
    assert (res["largest_m"], res["laws"]) == (int(m.group(1)), int(_num(m.group(3))))
    assert abs(2 * 16 / res["largest_m"] - float(m.group(2))) < 0.05


def test_design_page_table_rows_are_the_tables_targets():
    """docs/design.md's table: one row per wavelength that fits 16 cells and per layout design_table draws, in order."""
    from host_emulator.benchmarks.design_table import wall_layouts

    page = (ROOT / "docs" / "design.md").read_text()
    rows = re.findall(r"^\| (lambda|walls)=([\d.,]+) \| (\d+) % \| (\d+) % \|", page, re.M)
    lam = [float(v) for f, v, _, _ in rows if f == "lambda"]
    walls = [tuple(float(w) for w in v.split(",")) for f, v, _, _ in rows if f == "walls"]
    assert lam == [float(f"{30 / z:.6g}") for z in range(1, 16)]
    assert walls == wall_layouts(20)
    summary = re.findall(r"^(lambda|walls): (\d+) of (\d+) targets land in >= 90 % of the seeds$", page, re.M)
    for fam, ok, total in summary:
        fr = [int(s) for f, _, s, _ in rows if f == fam]
        assert (int(ok), int(total)) == (sum(s >= 90 for s in fr), len(fr))
    assert len(summary) == 2
