"""Shared fixtures: the host build of the shipped firmware library."""

import pytest


@pytest.fixture(scope="session")
def fw():
    """(ffi, lib) of the host build of lib/metacell (and the emulator C)."""
    from host_emulator import firmware

    return firmware.load()
