"""A 2-D sheet's results as data and pictures, from synthetic runs (no plant): the Dataset's (time, row, col) with
1-based row and col, the topology in the attributes, NPZ and NetCDF files that load back the same, a chain's Dataset
as before; the snapshots, the final field and the animation drawn for a sheet by `run` and `plot` alike."""

import json

import numpy as np
import pandas as pd
import pytest

import host_emulator as he
from host_emulator.cli import _print_summary
from host_emulator.scene import load_scene
from host_emulator.workbench.api import OBSERVABLE_KEYS, RunResult
from host_emulator.workbench.datasets import from_run, load, to_npz, write_run
from host_emulator.workbench.figures import plot_main
from host_emulator.workbench.inputs import as_run

ROWS, COLS = 3, 5


def synthetic(lattice="square", boundary="open", summary=None):
    """A RunResult of a 3 x 5 sheet whose alpha at sample k, cell j is k + j / 100 (cell order, row by row)."""
    sc = load_scene(
        "exp3_single_sigma9",
        [f"cells=[{ROWS},{COLS}]", f'lattice="{lattice}"', f'boundary="{boundary}"', "perturbation.1.cell=7"],
    )
    t = np.linspace(0.0, 0.4, 5)
    a = np.arange(5)[:, None] + np.arange(1, ROWS * COLS + 1)[None, :] / 100.0
    return RunResult(sc, t, a, -a, dict(summary or {}), 1.0)


def test_a_sheets_dataset_has_rows_and_cols_and_records_its_topology():
    r = synthetic(summary={"pattern_kind": "stripes", "dominant_wavelength_cells": 4.5})
    ds = r.to_xarray()
    assert ds["alpha"].dims == ("time", "row", "col") and ds["torque_alpha"].dims == ("time", "row", "col")
    assert list(ds["row"].values) == [1, 2, 3] and list(ds["col"].values) == [1, 2, 3, 4, 5]
    # row 2, col 4 is cell (2 - 1) * 5 + 4 = 9, and holds cell 9's samples
    assert int(ds["cell"].sel(row=2, col=4)) == 9
    np.testing.assert_array_equal(ds["alpha"].sel(row=2, col=4).values, r.alpha[:, 8])
    assert ds.attrs["topology.lattice"] == "square" and ds.attrs["topology.boundary"] == "open"
    assert list(ds.attrs["topology.cells"]) == [ROWS, COLS]
    assert ds.attrs["observable.pattern_kind"] == "stripes"
    assert ds.attrs["observable.dominant_wavelength_cells"] == 4.5


def test_a_chains_dataset_is_as_before():
    sc = load_scene("exp3_single_sigma9")
    t = np.linspace(0, 1, 3)
    a = np.ones((3, 16))
    ds = from_run(sc, t, a, -a)
    assert ds["alpha"].dims == ("time", "cell") and list(ds["cell"].values) == list(range(1, 17))
    assert not [k for k in ds.attrs if k.startswith("topology")] and ds.attrs["cells"] == 16


def test_the_observable_keys_are_one_list_for_runs_and_their_directories(tmp_path):
    """he.run's dataset and a run directory loaded back carry the same observables (one tuple, OBSERVABLE_KEYS)."""
    summary = {k: 1.0 for k in OBSERVABLE_KEYS} | {"source": "emulator:lattice", "scene": "x", "model": "lattice"}
    r = synthetic(summary=summary)
    d = tmp_path / "run"
    d.mkdir()
    write_run(d / "trajectories.npz", r.scene, r.time, r.alpha, r.beta, summary, "emulator:lattice")
    (d / "summary.json").write_text(json.dumps(summary))
    loaded, direct = load(d), r.to_xarray()
    for k in OBSERVABLE_KEYS:
        assert loaded.attrs[f"observable.{k}"] == direct.attrs[f"observable.{k}"] == 1.0, k


@pytest.mark.parametrize(("lattice", "boundary"), [("square", "open"), ("hex", "periodic")])
def test_saved_sheets_load_back(lattice, boundary, tmp_path):
    r = synthetic(lattice, boundary)
    ds = r.to_xarray()
    to_npz(ds, tmp_path / "s.npz")
    ds.to_netcdf(tmp_path / "s.nc", engine="scipy")
    d = tmp_path / "run"
    d.mkdir()
    write_run(d / "trajectories.npz", r.scene, r.time, r.alpha, r.beta, None, "emulator:lattice")
    for back in (load(tmp_path / "s.npz"), load(tmp_path / "s.nc"), load(d)):
        assert back["alpha"].dims == ("time", "row", "col")
        np.testing.assert_array_equal(back["alpha"].values, ds["alpha"].values)
        np.testing.assert_array_equal(back["cell"].values, ds["cell"].values)
        assert back.attrs["topology.lattice"] == lattice and back.attrs["topology.boundary"] == boundary
        view = as_run(back)
        np.testing.assert_array_equal(view.alpha, r.alpha)  # cell order again
        assert view.topology == r.scene.topology and view.params == r.scene.params
    # the catalogue lists a saved sheet without a chain's walls
    row = he.runs(tmp_path).set_index("path").loc["s.npz"]
    assert row["scene"] == "exp3_single_sigma9" and pd.isna(row["walls"])


def test_a_sheets_figures_are_snapshots_and_a_final_field(tmp_path, capsys):
    r = synthetic()
    fig = he.plot_spacetime(r)  # a sheet has no space-time map: its snapshots
    assert len(fig.axes) == 5  # 4 snapshots and their colorbar
    assert [ax.get_title() for ax in fig.axes[:4]] == ["t = 0.1 s", "t = 0.2 s", "t = 0.3 s", "t = 0.4 s"]
    img = fig.axes[3].get_images()[0].get_array()
    np.testing.assert_array_equal(img, r.alpha[-1].reshape(ROWS, COLS))  # row 1 at the top, as cells read
    fin = he.plot_final(r)
    assert [ax.get_title() for ax in fin.axes if ax.get_title()] == ["final alpha", "final beta"]
    hexf = he.plot_snapshots(synthetic("hex"), times=[0.0, 0.4])
    pcs = [ax.collections[0] for ax in hexf.axes[:2]]
    assert [len(pc.get_paths()) for pc in pcs] == [ROWS * COLS] * 2
    np.testing.assert_array_equal(pcs[1].get_array(), r.alpha[-1])
    # `plot PATH` of a saved sheet writes the same kinds of figure
    d = tmp_path / "run"
    d.mkdir()
    write_run(d / "trajectories.npz", r.scene, r.time, r.alpha, r.beta, None, "emulator:lattice")
    assert plot_main([str(d / "trajectories.npz"), "--out", str(tmp_path / "figs")]) == 0
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == [
        "dispersion.png",
        "final_pattern.png",
        "snapshots.png",
    ]


def test_the_animation_of_a_sheet_is_its_field(tmp_path):
    from host_emulator.workbench.animate import animate

    out = animate(synthetic("hex"), tmp_path / "a.gif", fps=5)
    from PIL import Image

    with Image.open(out) as im:
        assert im.n_frames == 5


def test_the_run_printout_of_a_sheet(capsys):
    s = {
        "scene": "s",
        "model": "lattice",
        "t_end_s": 1.0,
        "wall_s": 1.0,
        "realtime_factor": 1.0,
        "steady": True,
        "at_rest": False,
        "oscillation_period_s": None,
        "amplitude_rad": 1.2,
        "final_alpha_rad": [0.5, -1.25, 0.0],
        "pattern_kind": "spots",
        "dominant_wavelength_cells": 7.5,
    }
    topo = synthetic().scene.topology
    _print_summary(s, "out", [], topo)
    out = capsys.readouterr().out
    assert "  lattice: 3 x 5 square sheet (15 cells, open edges)\n" in out
    assert "pattern: spots   dominant wavelength: 7.5 cells" in out
    assert "final alpha (rad): -1.25 .. +0.50 over 3 cells" in out
    # a summary without the 2-D measures prints no line for them
    _print_summary(
        {k: v for k, v in s.items() if k not in ("pattern_kind", "dominant_wavelength_cells")}, "o", [], topo
    )
    out = capsys.readouterr().out
    assert "pattern:" not in out and "dominant wavelength" not in out
