"""A sweep over a sheet scene: pattern_kind and dominant_wavelength_cells per point (the summaries' own, kept
through sweep.nc) and the phase diagram of pattern kinds (pattern_kinds.png); a chain's points carry no kind."""

import math

import numpy as np
import pytest

pytest.importorskip("distributed")
xr = pytest.importorskip("xarray")

import host_emulator as he  # noqa: E402
from host_emulator.workbench.sweep import (  # noqa: E402
    PATTERN_KINDS,
    evaluate_points,
    plot_pattern_kinds,
    point_specs,
    sweep,
)
from host_emulator.workbench.sweep.kinds import kind_grid, theory_regimes  # noqa: E402

SIGMAS = [9 / 125, 14 / 125]
SCALES = [1.0, 1.1]
FIXED = ["t_end_s=4"]


def test_sheet_sweep_records_kinds_and_draws_their_phase_diagram(tmp_path):
    out = tmp_path / "sw"
    grid = {"params.sigma": SIGMAS, "params.band_scale": SCALES}
    ds = sweep("sheet_8x8", grid, out=out, fixed=FIXED, accuracy="fast", workers=1, progress=False)
    assert (ds["status"].values.astype(str) == "ok").all()
    assert ds["pattern_kind"].dims == ("sigma", "band_scale")
    assert ds["dominant_wavelength_cells"].attrs["units"] == "cells"
    # each point's kind and wavelength are its own summary's (the same run through he.run)
    for sg in SIGMAS:
        for bs in SCALES:
            s = he.run(
                "sheet_8x8", overrides={"params.sigma": sg, "params.band_scale": bs, "t_end_s": 4}, accuracy="fast"
            ).summary
            point = ds.sel(sigma=sg, band_scale=bs)
            assert str(point["pattern_kind"].values) == s["pattern_kind"]
            lam = float(point["dominant_wavelength_cells"].values)
            if s["dominant_wavelength_cells"] is None:
                assert math.isnan(lam)
            else:
                assert lam == pytest.approx(s["dominant_wavelength_cells"], rel=1e-12)
    # sigma = 9/125 grows a pattern; 14/125 is past the pattern regime (oscillation or rest)
    assert str(ds["pattern_kind"].sel(sigma=9 / 125, band_scale=1.0).values) in ("stripes", "spots", "labyrinth")
    assert str(ds["pattern_kind"].sel(sigma=14 / 125, band_scale=1.0).values) in ("oscillation", "rest")
    # the kinds survive sweep.nc
    back = xr.open_dataset(out / "sweep.nc", engine="scipy")
    np.testing.assert_array_equal(back["pattern_kind"].values.astype(str), ds["pattern_kind"].values.astype(str))
    np.testing.assert_array_equal(back["dominant_wavelength_cells"].values, ds["dominant_wavelength_cells"].values)
    # the figure: written, and its grid is the dataset's kinds (rows band_scale, columns sigma)
    png = out / "pattern_kinds.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    code, wave = kind_grid(xr.open_dataset(out / "sweep.nc", engine="scipy"), "sigma", "band_scale")  # lazy
    want = [
        [PATTERN_KINDS.index(str(ds["pattern_kind"].sel(sigma=sg, band_scale=bs).values)) for sg in SIGMAS]
        for bs in SCALES
    ]
    assert code.tolist() == want
    np.testing.assert_array_equal(wave, ds["dominant_wavelength_cells"].transpose("band_scale", "sigma").values)
    # the theory's regimes: stationary pattern at 9/125, no stationary band at 14/125 (analysis.stability)
    base = he.load_scene("sheet_8x8")
    reg = theory_regimes(back, base, "sigma", "band_scale")
    assert set(reg[:, 0]) == {"stationary_pattern"} and set(reg[:, 1]) == {"uniform_oscillation"}
    fig = plot_pattern_kinds(back, "sigma", None, base)  # one row over sigma (band_scale pooled)
    assert len(fig.axes) == 3  # kinds, wavelength, its colour bar


def test_chain_points_carry_no_kind():
    specs, _ = point_specs("default", {"params.sigma": [0.07]}, None, ["t_end_s=0.3"])
    (r,) = evaluate_points(specs)
    assert r["status"] == "ok" and r["pattern_kind"] == "" and math.isnan(r.get("dominant_wavelength_cells", math.nan))
