"""metacell_tools.experiment.compare: the table and overlay of a rig (or rehearsal) run against an emulator run."""

import json
import re

import numpy as np
import pytest

from metacell_tools.experiment.compare import CompareError, compare


def _summary(d, scene, alpha, beta, **kw):
    d.mkdir(parents=True, exist_ok=True)
    s = {
        "scene": scene,
        "model": kw.pop("model", "hil"),
        "final_alpha_rad": alpha,
        "final_beta_rad": beta,
        "pattern_period_cells": 5.0,
        "oscillation_period_s": None,
        **kw,
    }
    (d / "summary.json").write_text(json.dumps(s))
    return d


def test_compare_table_and_plot(tmp_path):
    emu = _summary(tmp_path / "emu", "x", [0.5, -0.5, 0.1], [0.1, 0.0, -0.1])
    rig = _summary(
        tmp_path / "rig",
        "x",
        [0.4, None, 0.1],
        [0.1, None, -0.2],
        model="rig",
        repeats=3,
        final_alpha_min_rad=[0.3, None, 0.0],
        final_alpha_max_rad=[0.6, None, 0.2],
    )
    text, png = compare(rig, emu, tmp_path / "c.png")
    assert png.stat().st_size > 1000
    rows = [ln for ln in text.splitlines() if re.match(r"\s+\d+\s", ln)]
    assert "-0.100" in rows[0] and "n/a" in rows[1]
    assert "rms difference: alpha 0.071 rad" in text  # sqrt((0.1^2 + 0^2) / 2)
    with pytest.raises(CompareError, match="different scenes"):
        compare(_summary(tmp_path / "other", "y", [0, 0, 0], [0, 0, 0]), emu)
    with pytest.raises(CompareError, match="not found"):
        compare(tmp_path / "nowhere", emu)


def test_compare_error_bars_tolerate_rounding_of_the_mean(tmp_path):
    v = float(np.mean([0.1, 0.1, 0.1]))  # 0.10000000000000002 > min = 0.1
    emu = _summary(tmp_path / "emu", "x", [0.1, 0.2], [0.0, 0.0])
    rig = _summary(
        tmp_path / "rig",
        "x",
        [v, v],
        [0.0, 0.0],
        model="rig",
        repeats=3,
        final_alpha_min_rad=[0.1, 0.1],
        final_alpha_max_rad=[0.1, 0.1],
    )
    text, png = compare(rig, emu)
    assert png.exists() and "+0.100" in text
