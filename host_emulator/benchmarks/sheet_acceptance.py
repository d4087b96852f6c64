"""Issue 30's acceptance on sheets in the lattice and hil tiers, one line each with its figure and PASS/FAIL.

    python -m host_emulator.benchmarks.sheet_acceptance [--no-paper] [--no-golden]

Checks (docs/sheets.md#acceptance): a sheet by `--set cells=[16,16]` and its summary.json keys; the 16 x 16 scene
(`sheet_16x16`, sigma = 9/125, one push at the centre) at its full duration in the lattice and in the hil, its
dominant wavelength inside the 2-D linear theory's unstable annulus and within 25 % of the fastest-growing
wavelength (the theory of the model that ran: inertia, the hil motors' back-EMF damping); the annulus and the
fastest wavelength themselves; pattern2d's kind on hand-made stripes and spots and on simulated regimes (stripes
seeded along one axis, the acceptance run's labyrinth, a spot at 6/125, rest and oscillation at 14/125); the 1-D results
unchanged (`paper` 14/14, the golden digests' test). Several minutes on a loaded machine (the paper check is most
of it): a benchmark, never a test. Exit status 0 when every line passes, 1 otherwise."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

WITHIN = 0.25  # the acceptance's: within 25 % of the fastest-growing wavelength
REPO = Path(__file__).resolve().parents[2]


def seeded_stripes_toml(t_end_s: float = 3.0) -> str:
    """A periodic 16 x 16 lattice sheet at 9/125 seeded with one Fourier mode along the rows: pushes of +-10 mN*m
    on every cell of columns 1, 5, 9, 13 (cos(2 pi (col - 1) / 8) at its extremes; 64 pushes, the plant's most),
    with a 5 % spread of the band stiffness per cell so that no two rows are the same sheet."""
    lines = [
        'name = "stripes_seeded"',
        'description = "periodic 16 x 16 sheet seeded with one mode along the rows"',
        'model = "lattice"',
        "cells = [16, 16]",
        'boundary = "periodic"',
        f"t_end_s = {t_end_s}",
        "[params]",
        "sigma = 0.072",
        "[model_options]",
        "inertia = true",
        'bands = "cubic"',
        'beta_geometry = "small"',
        "[model_options.noise]",
        "seed = 1",
        "band_spread = 0.05",
    ]
    for row in range(1, 17):
        for col in (1, 5, 9, 13):
            lines += ["[[perturbation]]", f"row = {row}", f"col = {col}", 'chain = "alpha"']
            lines += [f"torque_Nm = {0.01 if col in (1, 9) else -0.01}", "start_s = 0.1", "duration_s = 0.1"]
    return "\n".join(lines) + "\n"


def against_theory(summary: dict, scene) -> dict:
    """A sheet run's dominant wavevector against its model's 2-D linear theory: the lattice symbol at k* in an
    unstable stationary q-interval (inside the annulus), the annulus along the axis, the fastest wavelength along
    the axis and the relative distance from it."""
    from ..analysis import sheet
    from ..analysis.summary import theory_for

    th = theory_for(scene)
    an = sheet.annulus(scene.params, th)
    fa = sheet.fastest(scene.params, th)
    lam = summary["dominant_wavelength_cells"]
    if lam is None:
        return {"lambda": None, "in_annulus": False, "fastest": fa["lambda_cells"], "relative": math.inf}
    kr, kc = summary["dominant_wavevector"]
    q = float(sheet.symbol(scene.topology.kind, kr, kc))
    ivs = [iv for iv in an["intervals"] if iv["kind"] == "stationary"]
    return {
        "lambda": lam,
        "in_annulus": any(iv["q"][0] < q < iv["q"][1] for iv in ivs),
        "annulus": ivs[0]["discrete"]["axis"]["lambda_cells"] if ivs else None,
        "fastest": fa["lambda_cells"],
        "relative": lam / fa["lambda_cells"] - 1.0,
        "theory": th.label(),
    }


class Report:
    """Collects and prints the lines."""

    def __init__(self) -> None:
        self.results: list[bool] = []

    def line(self, what: str, figure: str, ok: bool | None, cpu_s: float | None = None) -> None:
        verdict = "PASS" if ok else ("FAIL" if ok is not None else "INFO")
        cost = f"  [{cpu_s:.1f} s CPU]" if cpu_s is not None else ""
        print(f"{verdict}  {what}: {figure}{cost}", flush=True)
        if ok is not None:
            self.results.append(bool(ok))


def _cli_run(args: list[str], out: Path) -> dict:
    """`python -m host_emulator run ARGS --quiet --out OUT` in this process; its summary.json."""
    from ..cli import main

    with contextlib.redirect_stdout(io.StringIO()):
        rc = main(["run", *args, "--quiet", "--out", str(out)])
    if rc != 0:
        raise RuntimeError(f"run {' '.join(args)} exited {rc}")
    return json.loads((out / "summary.json").read_text())


def _cpu() -> float:
    return time.process_time()


def check_sheets(rep: Report, tmp: Path) -> None:
    import host_emulator as he

    from ..analysis import pattern2d, sheet

    c = _cpu()
    s = _cli_run(["default", "--set", "cells=[16,16]"], tmp / "default_16x16")
    ok = (
        list(s["params"]["shape"]) == [16, 16]
        and s["pattern_kind"] in pattern2d.KINDS
        and "dominant_wavelength_cells" in s
    )
    rep.line(
        "`run default --set cells=[16,16]`: summary.json's sheet keys",
        f"params.shape {s['params']['shape']}, pattern_kind {s['pattern_kind']}, dominant_wavelength_cells "
        f"{s['dominant_wavelength_cells']}",
        ok,
        _cpu() - c,
    )
    runs = {}
    for model in ("lattice", "hil"):
        c = _cpu()
        args = ["sheet_16x16", "--model", model]
        s = _cli_run(args, tmp / f"sheet_16x16_{model}")
        sc = he.load_scene("sheet_16x16", {"model": model})
        got = against_theory(s, sc)
        runs[model] = s
        ok = got["in_annulus"] and abs(got["relative"]) <= WITHIN
        rep.line(
            f"16 x 16 at 9/125 pushed at (8, 8), {model}, {sc.t_end_s:g} s",
            f"{s['pattern_kind']}, wavelength {got['lambda']:.3f} cells; annulus (axis) "
            f"{got['annulus'][0]:.2f}-{got['annulus'][1]:.2f}, inside: {got['in_annulus']}; fastest "
            f"{got['fastest']:.3f} ({got['theory']}), {100 * got['relative']:+.1f} % (limit 25 %)",
            ok,
            _cpu() - c,
        )
    sc = he.load_scene("sheet_16x16")
    for model in ("lattice", "hil"):
        from ..analysis.summary import theory_for

        th = theory_for(he.load_scene("sheet_16x16", {"model": model}))
        an, fa = sheet.annulus(sc.params, th), sheet.fastest(sc.params, th)
        fs = sheet.finite_sheet(sc.params, th)
        ax, dg = an["intervals"][0]["discrete"]["axis"], an["intervals"][0]["discrete"]["diagonal"]
        top = fs["fastest_mode"]
        ok = fs["in_annulus"] and abs(fs["relative_to_fastest"]) <= WITHIN
        rep.line(
            f"2-D linear theory, {th.label()}",
            f"annulus axis {ax['lambda_cells'][0]:.3f}-{ax['lambda_cells'][1]:.3f}, diagonal "
            f"{dg['lambda_cells'][0]:.3f}-{dg['lambda_cells'][1]:.3f} cells; fastest axis {fa['lambda_cells']:.3f}, "
            f"diagonal {fa['discrete']['diagonal']['lambda_cells']:.3f}, continuum "
            f"{fa['continuum']['lambda_cells']:.3f} cells at {fa['growth_per_s']:.1f} 1/s; the open 16 x 16 "
            f"sheet's fastest mode {top['lambda_cells']:.2f} cells ({100 * fs['relative_to_fastest']:+.1f} %)",
            ok,
        )
    # the classifier: hand-made fields, then simulated regimes
    c = _cpu()
    from ..topology import Topology

    topo = Topology((32, 32), "square", False)
    r, col = np.divmod(np.arange(topo.n), topo.cols)
    k = 2 * math.pi / 8
    stripes = np.cos(k * (math.cos(0.3) * col + math.sin(0.3) * r))
    angles = (0.3, 0.3 + 2 * math.pi / 3, 0.3 - 2 * math.pi / 3)
    spots = np.sum([np.cos(k * (math.cos(a) * col + math.sin(a) * r)) for a in angles], axis=0)
    kinds = (pattern2d.classify(0.7 * stripes, topo), pattern2d.classify(0.3 * spots, topo))
    rep.line(
        "classifier, hand-made fields (32 x 32 open, wavelength 8)",
        f"plane wave -> {kinds[0]}, three waves at 120 degrees -> {kinds[1]}",
        kinds == ("stripes", "spots"),
        _cpu() - c,
    )
    c = _cpu()
    path = tmp / "stripes_seeded.toml"
    path.write_text(seeded_stripes_toml())
    st = he.run(str(path), accuracy="fast").summary
    rep.line(
        "classifier, simulated: periodic 16 x 16 seeded along the rows (lattice, 3 s)",
        f"{st['pattern_kind']}, wavelength {st['dominant_wavelength_cells']:.3f}, orientation "
        f"{st['orientation_deg']:.1f} deg, defects {st['defects']}",
        st["pattern_kind"] == "stripes",
        _cpu() - c,
    )
    lab = runs["lattice"]
    rep.line(
        "classifier, simulated: the acceptance run from one push (lattice, 25 s)",
        f"{lab['pattern_kind']} (boundary {lab['boundary_length_cells']} bonds, defects {lab['defects']})",
        lab["pattern_kind"] == "labyrinth",
    )
    c = _cpu()
    sp = he.run("sheet_16x16", {"params.sigma": 6 / 125, "t_end_s": 2.0}, accuracy="fast").summary
    rep.line(
        "classifier, simulated: 16 x 16 at 6/125, one push (lattice, 2 s): the push grows into one spot",
        f"{sp['pattern_kind']}, wavelength {sp['dominant_wavelength_cells']:.3f}",
        sp["pattern_kind"] == "spots",
        _cpu() - c,
    )
    c = _cpu()
    over = {"params.sigma": 14 / 125, "t_end_s": 2.0}
    osc = he.run("sheet_16x16", over, accuracy="fast")
    period = sheet.fastest(osc.scene.params, osc.theory)["period_s"]
    rest = he.run("sheet_16x16", {**over, "model": "hil", "t_end_s": 3.0}).summary
    so = osc.summary
    rep.line(
        "classifier, simulated: 16 x 16 at 14/125 (lattice 2 s; hil 3 s)",
        f"lattice {so['pattern_kind']} (period {1e3 * so['oscillation_period_s']:.1f} ms, theory "
        f"{1e3 * period:.1f} ms); hil {rest['pattern_kind']} (max |alpha| {rest['amplitude_rad']:.3f} rad)",
        so["pattern_kind"] == "oscillation" and rest["pattern_kind"] == "rest",
        _cpu() - c,
    )


def check_paper(rep: Report, tmp: Path) -> None:
    t0 = time.perf_counter()
    out = tmp / "paper"
    cmd = [sys.executable, "-m", "host_emulator", "paper", "--out", str(out), "--quiet"]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
    if p.returncode != 0 or not (out / "paper.json").exists():
        rep.line("1-D: `python -m host_emulator paper`", f"exit {p.returncode}: {p.stderr.strip()[-200:]}", False)
        return
    d = json.loads((out / "paper.json").read_text())
    rep.line(
        "1-D: `python -m host_emulator paper`",
        f"{d['agree']} of {d['total']} items agree ({time.perf_counter() - t0:.0f} s wall)",
        d["agree"] == d["total"] == 14,
    )


def check_golden(rep: Report) -> None:
    test = REPO / "tests" / "host_emulator" / "test_golden.py"
    if not test.exists():
        rep.line("1-D: golden digests", "tests/host_emulator/test_golden.py not found (run from a checkout)", False)
        return
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(test)]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)})
    m = re.search(r"(\d+) passed", p.stdout)
    failed = re.search(r"(\d+) failed", p.stdout)
    rep.line(
        "1-D: golden digests (`pytest tests/host_emulator/test_golden.py`)",
        f"{m.group(1) if m else 0} passed, {failed.group(1) if failed else 0} failed",
        p.returncode == 0 and m is not None,
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.sheet_acceptance", description=__doc__)
    ap.add_argument("--no-paper", action="store_true", help="skip the paper check (a few minutes)")
    ap.add_argument("--no-golden", action="store_true", help="skip the golden digests' test")
    args = ap.parse_args(argv)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; load {load}")
    rep = Report()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sheet_acceptance_") as d:
        check_sheets(rep, Path(d))
        if not args.no_golden:
            check_golden(rep)
        if not args.no_paper:
            check_paper(rep, Path(d))
    n, ok = len(rep.results), sum(rep.results)
    print(f"{ok} of {n} checks pass ({time.perf_counter() - t0:.0f} s wall; load at the end {os.getloadavg()[0]:.1f})")
    return 0 if ok == n else 1


if __name__ == "__main__":
    sys.exit(main())
