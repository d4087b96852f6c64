"""Cell lists accept ranges: 1-16, 1-4,7."""

import argparse

import pytest


def test_command_cells_accept_ranges():
    from metacell_tools.rigtools.command import _cells

    assert _cells("1-4,7") == [1, 2, 3, 4, 7]
    assert _cells("1-16") == list(range(1, 17)) == _cells("all")
    assert _cells("3,3-4") == [3, 4]
    for bad in ("4-1", "0-3", "1-17", "x", "", "-3"):
        with pytest.raises(argparse.ArgumentTypeError):
            _cells(bad)


def test_serve_cells_accept_ranges():
    from host_emulator.bus.serve import _cells

    assert _cells("3-5,9") == (3, 4, 5, 9)
    for bad in ("x", "5-3", "0", "1-17"):
        with pytest.raises(argparse.ArgumentTypeError):
            _cells(bad)
