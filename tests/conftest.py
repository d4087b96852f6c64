"""Shared fixtures: the host build of the shipped firmware library; matplotlib's Agg backend for every test."""

import os

import pytest
from hypothesis import HealthCheck, settings

# The suite must pass on a machine whose cores are saturated: no hypothesis example has a wall-clock deadline and
# slow data generation is not an error (the property is what is tested, not the speed). Tests that set their own
# settings inherit these defaults for what they leave out.
settings.register_profile("loaded-machine", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("loaded-machine")

# No window from any test (live plots included); subprocesses inherit it. The package itself never selects
# a backend: this is the test environment's choice.
os.environ["MPLBACKEND"] = "Agg"


def ctrl_c_default() -> None:
    """preexec_fn for a child that a test interrupts with SIGINT: Ctrl-C's default action, even when the suite itself
    runs with SIGINT ignored (a background job of a non-interactive shell), which Python children would inherit."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture(scope="session")
def fw():
    """(ffi, lib) of the host build of lib/metacell (and the emulator C)."""
    from host_emulator import firmware

    return firmware.load()
