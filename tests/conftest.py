"""Shared fixtures: the host build of the shipped firmware library; matplotlib's Agg backend for every test."""

import os

import pytest

# No window from any test (live plots included); subprocesses inherit it. The package itself never selects
# a backend: this is the test environment's choice.
os.environ["MPLBACKEND"] = "Agg"


@pytest.fixture(scope="session")
def fw():
    """(ffi, lib) of the host build of lib/metacell (and the emulator C)."""
    from host_emulator import firmware

    return firmware.load()
