"""The primary's image against the I2C bus states as silicon has them: SDA pulled low by a fault while the primary's
SERCOM2 is idle is a START by someone else (STATUS.BUSSTATE BUSY, DS40001882 Figure 28-4), and the primary's code
takes its BUSY path (primary_hw_txn: a bus recovery, no transaction); SDA let go is a STOP (IDLE), and the polling
goes on. The SCL timing the shipped primary sets is within Fast-mode's limits."""

from __future__ import annotations

import re

import pytest

from .conftest import configured

pytestmark = pytest.mark.slow

FAULTS = 6  # stuck-SDA faults, each at another phase of the primary's poll (one transaction every ~80 us)
PHASE_S = 13e-6
EVERY_S = 2e-3
STUCK_S = 0.4e-3


def _paths(notes: list[str]) -> list[str]:
    """For each fault, what the primary did first after SDA went low: "busy" (its SERCOM disabled for a recovery
    without a lost arbitration: BUSSTATE read BUSY) or "arblost" (the fault caught it in a transaction)."""
    out = []
    current = None
    for n in notes:
        if "primary <- primary M_SDA arg 1" in n:
            current = "open"
        elif current == "open" and "primary <- primary M_ARBLOST" in n:
            current = "arblost"
        elif current == "open" and re.search(r" primary W SERCOM2\.I2CM\.CTRLA = 0x([0-9a-f]+) ", n):
            enable = int(re.search(r"= 0x([0-9a-f]+) ", n).group(1), 16) & 2
            if not enable:
                current = "busy"
        elif "primary <- primary M_SDA arg 0" in n and current is not None:
            out.append(current)
            current = None
    return out


def test_a_stuck_sda_while_idle_takes_the_primarys_busy_path_and_it_recovers(images):
    """Stuck-SDA faults of 0.4 ms at six phases of the poll: where one begins between transactions the primary
    reads BUSSTATE BUSY and recovers the bus without starting a transaction (on today's main BUSSTATE never became
    BUSY: every fault was an ARBLOST); once SDA is let go the cell's samples flow again, with no reset."""
    w, lap = configured(images, 1, start_plant=False)
    lap.pump(0.01)
    prim = next(b.index for b in w.boards if b.role == "primary")
    t = w.t + 0.001
    for k in range(FAULTS):
        t0 = t + k * EVERY_S + k * PHASE_S
        w.fault("stuck_sda", t0, t0 + STUCK_S)
    w.take_notes()
    w.trace(1 | 32, 1 << prim)
    lap.pump(t + FAULTS * EVERY_S - w.t)
    w.trace(0, 0)
    paths = _paths(w.take_notes())
    assert len(paths) == FAULTS, paths
    assert "busy" in paths, f"no fault met the primary idle: {paths}"
    before = lap.rx.samples
    bus = w.bus_info()
    lap.pump(0.02)
    assert lap.rx.samples > before, "no samples from the cell once SDA was let go"
    after = w.bus_info()
    assert after.transactions > bus.transactions and after.arblost == bus.arblost and after.buserr == 0
    assert w.info(prim).resets == 1


def test_the_shipped_primary_sets_fast_mode_timing(images):
    """At 400 kHz the primary's BAUD 48 / BAUDLOW 62 at 48 MHz give T_LOW 67 / 48 MHz = 1.396 us >= 1.3 us and
    T_HIGH 53 / 48 MHz = 1.104 us >= 0.6 us (docs/hardware.md "SCL generation"), SDAHOLD 300-600 ns leaves a data
    setup of 1.396 - 0.6 - 0.125 = 0.671 us >= 0.1 us: no violation, no note."""
    w, lap = configured(images, 1, start_plant=False)
    prim = next(b.index for b in w.boards if b.role == "primary")
    t = w.ffi.new("sam_i2c_timing_t *")
    assert w.lib.sam_world_i2c_timing(w._w, prim, t) == 0
    assert (t.baud, t.baudlow, t.sdahold, t.mode) == (48, 62, 2, w.lib.SAM_I2C_FAST)
    assert t.t_low_s == pytest.approx(67 / 48e6) and t.t_high_s == pytest.approx(53 / 48e6)
    assert t.t_setup_s == pytest.approx(67 / 48e6 - 600e-9 - 125e-9)
    assert t.violations == 0
    assert not [n for n in w.notes() if "SCL timing" in n]
