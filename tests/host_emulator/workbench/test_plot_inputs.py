"""Plots from anything: he.plot_* take a RunResult, a Dataset (to_xarray, he.load), a run directory or a capture path,
and draw the data of that input; `plot` and `run --format` write PNG, PDF or SVG, a paper column wide on request."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

import host_emulator as he
from host_emulator.cli import main
from host_emulator.workbench.datasets import from_logger_arrays, to_npz
from protocol.capture import CSV_HEADER, RAD_PER_COUNT, format_rows, rows_to_arrays

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def run_and_files(tmp_path_factory):
    """One short run of the default scene, its run directory (the CLI's), and a logger capture of it (CSV alone,
    and the run-layout NPZ the logger writes) with cell 5's sample of one cycle missing."""
    tmp = tmp_path_factory.mktemp("inputs")
    r = he.run("default", overrides={"t_end_s": 0.8})
    run_dir = tmp / "run"
    assert main(["run", "default", "--set", "t_end_s=0.8", "--out", str(run_dir), "--quiet", "--no-plots"]) == 0
    counts_a = np.round(r.alpha / RAD_PER_COUNT).astype(int)
    counts_b = np.round(r.beta / RAD_PER_COUNT).astype(int)
    rows = []
    for k in range(len(r.time)):
        for j in range(1, 17):
            if (k, j) == (40, 5):
                continue
            rows.append((0, k, j, float(r.time[k]), 1000.0 + r.time[k], counts_a[k, j - 1], counts_b[k, j - 1], 0))
    cap_csv = tmp / "cap.csv"
    cap_csv.write_text(CSV_HEADER + format_rows(rows))
    arr = rows_to_arrays(np.array(rows, dtype=float), 16, [])
    cap_npz = to_npz(from_logger_arrays(arr, {"source": "rig"}), tmp / "rig1.npz")
    return r, run_dir, cap_csv, cap_npz, counts_a


def _inputs(r, run_dir, cap_csv, cap_npz):
    return {
        "RunResult": r,
        "to_xarray": r.to_xarray(),
        "run dir (str)": str(run_dir),
        "run dir (Path)": run_dir,
        "he.load(run dir)": he.load(run_dir),
        "capture CSV": cap_csv,
        "capture NPZ": str(cap_npz),
        "he.load(capture)": he.load(cap_npz),
    }


def test_every_plot_takes_every_input_and_draws_its_data(run_and_files):
    r, run_dir, cap_csv, cap_npz, counts_a = run_and_files
    want_final = counts_a[-1] * RAD_PER_COUNT
    for label, x in _inputs(r, run_dir, cap_csv, cap_npz).items():
        capture = "capture" in label
        fig = he.plot_spacetime(x)
        img = fig.axes[0].images[0].get_array()
        ref = counts_a * RAD_PER_COUNT if capture else r.alpha
        got = np.ma.filled(img.astype(float), np.nan).T  # cells x time, drawn as the image
        if capture:
            assert np.isnan(got[40, 4]), label  # the missing sample stays missing
            got[40, 4] = ref[40, 4]
        np.testing.assert_allclose(got, ref, atol=1e-12, err_msg=label)
        title = fig.axes[0].get_title()
        assert ("default" in title) if not capture else ("rig" in title or "cap" in title), (label, title)
        if not capture:
            assert "sigma = 0.072" in title and "alpha_8" in title, (label, title)
        fig = he.plot_final(x)
        alpha_line = fig.axes[0].get_lines()[0].get_ydata()
        np.testing.assert_allclose(alpha_line, want_final if capture else r.alpha[-1], atol=1e-12, err_msg=label)


def test_plot_dispersion_takes_a_run_and_uses_its_model(run_and_files):
    r, run_dir, cap_csv, cap_npz, _ = run_and_files
    ref_ax = Figure().add_subplot(111)
    he.plot_dispersion(r.scene.params, ax=ref_ax, theory=r.theory)
    ref = [ln.get_ydata() for ln in ref_ax.get_lines()]
    for label, x in _inputs(r, run_dir, cap_csv, cap_npz).items():
        ax = Figure().add_subplot(111)
        if "capture" in label:
            with pytest.raises(ValueError, match="no parameters"):
                he.plot_dispersion(x, ax=ax)
            continue
        he.plot_dispersion(x, ax=ax)
        got = [ln.get_ydata() for ln in ax.get_lines()]
        assert len(got) == len(ref), label
        for a, b in zip(got, ref):
            np.testing.assert_allclose(a, b, err_msg=label)


def test_a_plot_of_something_else_is_a_clear_error(tmp_path):
    with pytest.raises(TypeError, match="RunResult, an xarray Dataset, a run directory or a capture path"):
        he.plot_spacetime(42)
    from host_emulator.workbench.datasets import LoadError

    with pytest.raises(LoadError, match="no such file"):
        he.plot_final(tmp_path / "nothing-here")


def _pdf_width_in(path: Path) -> float:
    box = re.search(rb"/MediaBox \[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", path.read_bytes())
    assert box, path
    return float(box.group(1)) / 72


def test_plot_command_writes_pdf_and_svg_a_column_wide(run_and_files, tmp_path, capsys):
    r, run_dir, cap_csv, cap_npz, _ = run_and_files
    out = tmp_path / "figs"
    assert main(["plot", str(run_dir), "--out", str(out), "--format", "pdf", "--column"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["dispersion.pdf", "final_pattern.pdf", "spacetime.pdf"]
    for p in out.iterdir():
        assert p.read_bytes()[:5] == b"%PDF-"
        assert abs(_pdf_width_in(p) - 3.4) < 0.01, p
    assert main(["plot", str(cap_npz), "--out", str(out), "--format", "svg"]) == 0
    svgs = sorted(p.name for p in out.glob("*.svg"))
    assert svgs == ["final_pattern.svg", "spacetime.svg"]  # a capture carries no parameters: no dispersion
    assert b"<svg" in (out / "spacetime.svg").read_bytes()[:2000]
    capsys.readouterr()


def test_plot_command_rejects_an_unreadable_input_in_one_line_leaving_nothing(tmp_path):
    out = tmp_path / "never"
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    for src in (tmp_path / "missing", bad):
        r = subprocess.run(
            [sys.executable, "-m", "host_emulator", "plot", str(src), "--out", str(out)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert r.returncode == 2, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr, r.stderr
        assert not out.exists()


def test_run_format_svg_writes_svg_plots(tmp_path, capsys):
    import json

    out = tmp_path / "r"
    assert main(["run", "default", "--set", "t_end_s=0.3", "--out", str(out), "--quiet", "--format", "svg"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["files"][2:] == ["spacetime.svg", "final_pattern.svg", "dispersion.svg"]
    for f in s["files"][2:]:
        assert b"<svg" in (out / f).read_bytes()[:2000]
    assert not list(out.glob("*.png"))
    capsys.readouterr()
