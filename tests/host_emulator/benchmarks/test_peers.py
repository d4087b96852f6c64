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
