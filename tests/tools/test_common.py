"""metacell_common and the moved pieces: the reaction defaults are the firmware's, and every old import path names the
very object of its new home (the emulator, the tools and the tests keep working through them)."""

import importlib

import pytest

from metacell_common.reaction import REACTION_DEFAULTS, REACTION_KEYS, REACTION_REGISTERS
from protocol import codec

# (old module, name, new module): the old path re-exports the new home's object
MOVED = [
    ("host_emulator.firmware", "load", "metacell_common.firmware"),
    ("host_emulator.firmware", "FirmwareBuildError", "metacell_common.firmware"),
    ("host_emulator.outpaths", "check_out_dir", "metacell_common.outpaths"),
    ("host_emulator.provenance", "provenance", "metacell_common.provenance"),
    ("host_emulator.progress", "bar", "metacell_common.progress"),
    ("host_emulator.cli", "unexpected", "metacell_common.cli"),
    ("host_emulator.params", "REACTION_KEYS", "metacell_common.reaction"),
    ("host_emulator.workbench.datasets", "write_npz", "metacell_common.runlayout"),
    ("host_emulator.workbench.datasets", "logger_layout", "metacell_common.runlayout"),
    ("host_emulator.workbench.datasets", "save_npz_atomic", "metacell_common.runlayout"),
    ("host_emulator.workbench.trackers", "Tracker", "host_emulator.tracking"),
    ("host_emulator.workbench.trackers", "RecordTracker", "host_emulator.tracking"),
    ("host_emulator.workbench.trackers", "ProgressTracker", "host_emulator.tracking"),
    ("host_emulator.controller", "RunResult", "host_emulator.result"),
    ("host_emulator.controller", "build_solver", "host_emulator.construct"),
    # the guarded solver's one home, as its callers import it (limits' lazy re-export of both is gone)
    ("host_emulator.controller", "checked_solver", "host_emulator.construct"),
    ("host_emulator.workbench.sweep.driver", "scene_cost", "host_emulator.construct"),
    ("host_emulator.image.cycles", "CycleModel", "metacell_common.target.cycles"),
    ("host_emulator.image.cycles", "FLASH_SIZE", "metacell_common.target.board"),
    ("host_emulator.image.board", "CELL_WIRING", "metacell_common.target.wiring"),
    ("host_emulator.image.board", "pin_number", "metacell_common.target.wiring"),
    ("metacell_tools.fwcheck.cpubudget", "CycleModel", "metacell_common.target.cycles"),
    ("metacell_tools.fwcheck.cpubudget", "parse_disassembly", "metacell_common.target.cycles"),
    ("metacell_tools.fwcheck.cpubudget", "max_edge_rate_hz", "metacell_common.target.board"),
    ("metacell_tools.fwcheck.cpubudget", "Analyser", "metacell_tools.fwcheck.wcet"),
    ("metacell_tools.fwcheck.armbuild", "ToolError", "metacell_common.target.toolchain"),
    ("metacell_tools.flash.plan", "board_build_env", "metacell_common.target.build"),
    ("metacell_tools.rigtools.portlock", "holders", "metacell_common.portlock"),
    ("metacell_tools.rigtools.logger", "rows_to_arrays", "protocol.capture"),
    ("metacell_tools.rigtools.logger", "partial_cycles", "protocol.capture"),
    ("metacell_tools.rigtools.logger", "read_rows", "protocol.capture"),
    ("metacell_tools.experiment.runner", "cells_text", "metacell_common.cli"),
]


@pytest.mark.parametrize("old, name, new", MOVED, ids=[f"{o}.{n}" for o, n, _ in MOVED])
def test_old_paths_name_the_new_homes_objects(old, name, new):
    assert getattr(importlib.import_module(old), name) is getattr(importlib.import_module(new), name)


def test_the_loggers_decoder_is_the_capture_decoder_that_also_saves():
    from metacell_tools.rigtools.logger import SampleDecoder
    from protocol import capture

    assert issubclass(SampleDecoder, capture.SampleDecoder) and hasattr(SampleDecoder, "save")


def test_reaction_defaults_are_the_firmwares(fw):
    """mc_cell_default_params (lib/metacell/src/mc_cell.c) holds what REACTION_DEFAULTS says, register by register;
    Params' defaults are the same values."""
    from host_emulator.params import Params

    ffi, lib = fw
    p = ffi.new("mc_reaction_phys_t *")
    lib.mc_cell_default_params(p)
    member = {"k_ab": "k_ab_unm", "sigma": "sigma_unm", "k1": "k1_unm", "k2": "k2_unm", "alpha_star": "astar_urad"}
    assert set(REACTION_KEYS) == set(REACTION_DEFAULTS) == set(REACTION_REGISTERS) == set(member)
    for name, reg in REACTION_REGISTERS.items():
        assert getattr(p, member[name]) == codec.to_register(reg, "value", REACTION_DEFAULTS[name]), name
        assert getattr(Params(), name) == REACTION_DEFAULTS[name]
