"""A sheet runs as a sheet, end to end (the compiled plant on the sheet's bonds; 0.5 s of the 16 x 16 scene at
most): `run` prints the lattice and writes the sheet's files, its dataset puts every cell at its (row, col), and
the pattern a push grows into is the sheet's own (mirror-symmetric about the diagonal through a push on it, which
a chain of the same cells is not)."""

import json

import numpy as np

import host_emulator as he
from host_emulator.cli import main
from host_emulator.workbench.datasets import load


def test_run_a_sheet_prints_its_lattice_and_writes_its_files(tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["run", "sheet_16x16", "--set", "t_end_s=0.3", "--set", "perturbation.1.row=3"]
    assert main([*argv, "--set", "perturbation.1.col=10", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "  lattice: 16 x 16 square sheet (256 cells, open edges)\n" in printed
    assert "final alpha (rad): " in printed and " over 256 cells" in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["perturbation"][0]["row"] == 3 and s["perturbation"][0]["col"] == 10
    # the summary's 2-D measures (analysis.pattern2d) in the printout, and on the dataset as observable.*
    assert f"  pattern: {s['pattern_kind']}   dominant wavelength: " in printed
    assert s["pattern_kind"] in ("stripes", "spots", "labyrinth", "rest", "oscillation")
    assert {"snapshots.png", "final_pattern.png"} <= set(s["files"]) and (out / "snapshots.png").exists()
    ds = load(out)
    assert ds["alpha"].dims == ("time", "row", "col") and ds.sizes["row"] == ds.sizes["col"] == 16
    assert ds.attrs["observable.pattern_kind"] == s["pattern_kind"]
    assert list(ds.attrs["topology.cells"]) == [16, 16] and ds.attrs["topology.lattice"] == "square"
    # just after the push (0.1-0.2 s) the pushed cylinder, at row 3 col 10, leads every other
    a = ds["alpha"].sel(time=0.2, method="nearest")
    peak = a.where(abs(a) == abs(a).max(), drop=True)
    assert (int(peak["row"][0]), int(peak["col"][0])) == (3, 10)
    assert int(ds["cell"].sel(row=3, col=10)) == 2 * 16 + 10


def test_a_push_on_the_diagonal_grows_a_pattern_symmetric_about_it():
    """The square sheet and a push at (8, 8) are symmetric under swapping rows and columns, so the field is too (to
    rounding); the same cells run as a chain (bonds j, j + 1 only) are not."""
    r = he.run("sheet_16x16", {"t_end_s": 0.5})
    grid = r.scene.topology.grid(r.alpha[-1])
    assert np.abs(grid).max() > 0.1  # the push has grown
    np.testing.assert_allclose(grid, grid.T, rtol=0, atol=1e-9)
    chain = he.run("sheet_16x16", {"t_end_s": 0.5, "cells": 256, "lattice": "chain", "perturbation.1.cell": 120})
    g = r.scene.topology.grid(chain.alpha[-1])
    assert np.abs(g - g.T).max() > 1e-3
