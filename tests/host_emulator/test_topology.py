"""Topology: bonds, numbering and the Laplacian's symbol against an independent dense eigen-solve."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.params import Params
from host_emulator.topology import Topology, TopologyError


def test_chain_bonds_are_the_golden_order():
    t = Params().topology
    assert t.is_open_chain and t.n == 16
    assert t.bonds.tolist() == [[j, j + 1] for j in range(15)]
    ring = Topology.chain(5, periodic=True)
    assert ring.bonds.tolist()[-1] == [4, 0] and ring.nbond == 5


@settings(max_examples=30, deadline=None)
@given(st.integers(3, 7), st.integers(3, 7), st.sampled_from(["square", "hex"]))
def test_periodic_spectrum_is_the_symbol(rows, cols, kind):
    t = Topology((rows, cols), kind, periodic=True)
    eig = np.sort(np.linalg.eigvalsh(t.laplacian().toarray()))
    k1, k2 = np.meshgrid(2 * np.pi * np.arange(cols) / cols, 2 * np.pi * np.arange(rows) / rows)
    assert np.allclose(eig, np.sort(t.symbol(k1, k2).ravel()), atol=1e-9)
    assert set(t.degree()) == {4 if kind == "square" else 6}


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 9), st.integers(1, 9))
def test_open_sheet_counts_and_numbering(rows, cols):
    t = Topology((rows, cols), "square")
    assert t.nbond == rows * (cols - 1) + cols * (rows - 1)
    for cell in range(1, t.n + 1):
        assert t.cell_of(*t.row_col(cell)) == cell
    # every bond joins cells one step apart
    p = t.positions()
    d = np.linalg.norm(p[t.bonds[:, 0]] - p[t.bonds[:, 1]], axis=1)
    assert np.allclose(d, 1.0)
    assert len({tuple(sorted(b)) for b in t.bonds.tolist()}) == t.nbond


def test_hex_neighbours_are_one_spacing_apart():
    t = Topology((4, 5), "hex")
    p = t.positions()
    d = np.linalg.norm(p[t.bonds[:, 0]] - p[t.bonds[:, 1]], axis=1)
    assert np.allclose(d, 1.0)
    assert t.degree().max() == 6


@pytest.mark.parametrize(
    "cells, lattice, boundary, msg",
    [
        ([4, 0], None, "open", "two whole numbers"),
        ([4, 4, 4], None, "open", "two whole numbers"),
        ([4, 4], "chain", "open", "one number"),
        ([4, 4], "tri", "open", "expected one of"),
        (16, "square", "open", "needs cells = [rows, cols]"),
        ([2, 4], None, "periodic", "at least 3 rows"),
        (2, None, "periodic", "at least 3 cells"),
        (16, None, "wrapped", "boundary"),
        ([4.0, 4], None, "open", "whole numbers"),
    ],
)
def test_bad_specs_are_one_line_errors(cells, lattice, boundary, msg):
    with pytest.raises(TopologyError, match=re.escape(msg)) as e:
        Topology.from_spec(cells, lattice, boundary)
    assert "\n" not in str(e.value)


def test_params_shape_must_hold_cells():
    with pytest.raises(TopologyError, match="holds 16"):
        _ = Params(cells=15, shape=(4, 4), lattice="square").topology
