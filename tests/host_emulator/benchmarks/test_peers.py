"""Compiled peers of the work-precision bench: a missing package is one skip line; peers never count as ours."""

from __future__ import annotations

import sys

import numpy as np

from host_emulator.benchmarks import peers
from host_emulator.benchmarks import workprecision as wp
from host_emulator.benchmarks.common import WPPoint


def test_missing_peer_is_skipped_with_one_line(monkeypatch):
    monkeypatch.setitem(sys.modules, "sksundae", None)
    monkeypatch.setitem(sys.modules, "sksundae.cvode", None)
    monkeypatch.setitem(sys.modules, "jax", None)
    lines = []
    scene = wp.lattice_scene(0.3)
    t = wp.output_times(0.3, 0.01)
    assert peers.cvode_points(scene, t, np.zeros(64), np.zeros((len(t), 32)), log=lines.append) == []
    assert peers.diffrax_points(scene, t, np.zeros(64), np.zeros((len(t), 32)), log=lines.append) == []
    assert len(lines) == 2 and all("skipped" in s and "bench" in s for s in lines)


def test_peers_are_not_counted_as_ours():
    pts = [
        WPPoint("rk4", "a", 0.01, 1e-5),
        WPPoint("rk4", "b", 0.005, 1e-3),
        WPPoint("diffrax Tsit5", "a", 0.001, 1e-5),
        WPPoint("diffrax Tsit5", "b", 0.0005, 1e-3),
        WPPoint("CVODE Adams", "a", 0.02, 1e-5),
        WPPoint("CVODE Adams", "b", 0.01, 1e-3),
    ]
    _, best, peer = wp.summarize(pts, 1e-4, ours_prefix=("diffrax",))
    assert best[0] == "rk4" and peer[0] == "diffrax Tsit5"
    _, best, peer = wp.summarize(pts, 1e-4)
    assert best[0] == "rk4" and peer is None


def test_front_ratios_pick_the_best_of_each_side_per_error():
    """Two of ours (rk4 cheap and loose, dop853 tight) against two diffrax solvers and CVODE: at each error the
    cheapest of ours and of each family, interpolated log-log on each method's front; None where nobody gets."""
    pts = [
        WPPoint("rk4", "a", 0.002, 1e-3),
        WPPoint("rk4", "b", 0.020, 1e-6),
        WPPoint("dop853", "a", 0.003, 1e-4),
        WPPoint("dop853", "b", 0.004, 1e-8),
        WPPoint("diffrax Tsit5", "a", 0.010, 1e-3),
        WPPoint("diffrax Tsit5", "b", 0.100, 1e-7),
        WPPoint("diffrax Dopri8", "a", 0.012, 1e-4),
        WPPoint("diffrax Dopri8", "b", 0.016, 1e-8),
        WPPoint("CVODE Adams", "a", 0.040, 1e-3),
        WPPoint("CVODE Adams", "b", 0.080, 1e-6),
    ]
    rows = {r["tol_rad"]: r for r in wp.front_ratios(pts, (1e-3, 1e-8, 1e-9))}
    r = rows[1e-3]
    assert (r["ours_method"], r["best_peer"]) == ("rk4", "diffrax Tsit5")
    assert np.allclose([r["ours_ms"], r["peer_ms"], r["ratio"], r["peers"]["CVODE"]["ratio"]], [2.0, 10.0, 5.0, 20.0])
    assert "scipy" not in r["peers"]
    r = rows[1e-8]
    assert (r["ours_method"], r["best_peer"]) == ("dop853", "diffrax Dopri8") and abs(r["ratio"] - 4.0) < 1e-12
    assert "CVODE" not in r["peers"]  # CVODE never reaches 1e-8 here
    r = rows[1e-9]
    assert r["ours_method"] is None and r["best_peer"] is None and r["ratio"] is None
    assert set(rows[1e-3]) >= {"tol_rad", "ours_ms", "ours_method", "best_peer", "peer_ms", "ratio"}
