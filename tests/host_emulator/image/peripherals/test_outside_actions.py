"""Actions from outside the boards (a reset the USB host or the flash tool asks for, an injected fault) reaching a
board whose clock a stall has moved past the world's time: they land at the board's own time, never in its past.
NVMCTRL's row erase stalls the CPU for 0.85 ms (csrc/sam_nvmctrl.c), so after one the board is ahead of the world by
more than the 50 us an outside action is given (World.reset: the world's time + API_S)."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness

NVM = 0x4100_4000
KEY, CMD_ER = 0xA5 << 8, 0x02
FREE = 0x8000  # a flash row the stub (at 0x2000) does not use
API_S = 50e-6


def stalled() -> tuple[Harness, int, int]:
    """A harness whose board 0 has just erased a row: (harness, world time, board time), board ahead of the world."""
    h = Harness()
    h.advance(0.001)
    h.write("NVMCTRL.ADDR", FREE >> 1)
    h.write("NVMCTRL.CTRLA", KEY | CMD_ER)
    world, board = int(h.lib.sam_world_time(h._w)), h.now()
    assert board > world + h.tu(API_S), "the erase did not put the board ahead (the test tests nothing)"
    return h, world, board


@pytest.mark.parametrize("kind", ["SAM_FAULT_RESET", "SAM_FAULT_RESET_BUTTON", "SAM_FAULT_HARDFAULT"])
def test_an_outside_action_due_in_a_stalled_boards_past_lands_at_its_own_time(kind):
    h, world, board = stalled()
    resets, faults = h.info().resets, h.info().hardfaults
    t0 = world + h.tu(API_S)
    assert h.lib.sam_world_fault(h._w, getattr(h.lib, kind), 0, t0, t0, 0.0, 0) == 0
    h.advance(0.002)  # used to stop: "the boards wait for each other ... (scheduling error)"
    info = h.lib.sam_world_nfaults(h._w)
    out = h.ffi.new("sam_fault_info_t *")
    assert h.lib.sam_world_fault_info(h._w, info - 1, out) == 0
    assert out.fired and out.t_fired >= board, (int(out.t_fired), board)
    if kind == "SAM_FAULT_HARDFAULT":
        assert h.info().hardfaults > faults or h.info().lockup
    else:
        assert h.info().resets == resets + 1
