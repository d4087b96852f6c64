"""SERCOM2 I2C master on the register-level harness: its SCL timing from BAUD, BAUDLOW and SDAHOLD against hand-computed
datasheet values and the I2C-bus specification's limits, what a violation does on the bus, and the bus states
(UNKNOWN, IDLE, OWNER, BUSY), BUSERR and ARBLOST with the stuck-SDA fault (DS40001882 28.6.2.4.1 Clock Generation,
Figure 28-4 Bus State Diagram, 28.10.8 STATUS; NXP UM10204 Table 10)."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness

from .bench import sercom2_i2c_pins

SLAVE, MASTER = 0, 1  # board indices
ADDR = 0x42
ENABLE = 1 << 1
MODE_SLAVE, MODE_MASTER = 0x4 << 2, 0x5 << 2  # CTRLA.MODE
SDAHOLD_POS = 20  # CTRLA.SDAHOLD[21:20]: 0 off, 1 50-100 ns, 2 300-600 ns, 3 400-800 ns
INACTOUT_POS = 28  # CTRLA.INACTOUT[29:28]: 0 off, 1 5-6, 2 10-11, 3 20-21 SCL cycles
M_MB, M_SB, M_ERROR = 1 << 0, 1 << 1, 1 << 7  # I2CM.INTFLAG
S_AMATCH = 1 << 1  # I2CS.INTFLAG
BUSERR, ARBLOST, RXNACK = 1 << 0, 1 << 1, 1 << 2  # I2CM.STATUS
UNKNOWN, IDLE, OWNER, BUSY = 0, 1, 2, 3  # STATUS.BUSSTATE
CMD_STOP = 0x3 << 16
RISE = 125e-9  # the harness's bus rise time (cfg.i2c_rise_ns)
T1 = 10e-6 + RISE  # SCL period at 1 MHz with BAUD 0


def bus(
    baud: int = 0, sdahold: int = 0, osc8m_presc: int = 3, enable: bool = True, force: bool = True, inactout: int = 0
) -> Harness:
    """A cell as the slave at ADDR and a primary as the master (BAUD, SDAHOLD, INACTOUT), the master's GCLK0 OSC8M >>
    presc (3: the reset value, 1 MHz; 0: 8 MHz)."""
    h = Harness(boards=("cell", "primary"))
    sercom2_i2c_pins(h, (SLAVE, MASTER))
    if osc8m_presc != 3:
        h.write("SYSCTRL.OSC8M", h.read("SYSCTRL.OSC8M", board=MASTER) & ~(3 << 8) | osc8m_presc << 8, board=MASTER)
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE, board=SLAVE)
    h.write("SERCOM2.I2CS.ADDR", ADDR << 1, board=SLAVE)
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE | ENABLE, board=SLAVE)
    ctrla = MODE_MASTER | sdahold << SDAHOLD_POS | inactout << INACTOUT_POS
    h.write("SERCOM2.I2CM.CTRLA", ctrla, board=MASTER)
    h.write("SERCOM2.I2CM.BAUD", baud, board=MASTER)
    if enable:
        h.write("SERCOM2.I2CM.CTRLA", ctrla | ENABLE, board=MASTER)
        h.advance(20e-6)
        if force:
            h.write("SERCOM2.I2CM.STATUS", IDLE << 4, board=MASTER)
            h.advance(20e-6)
    return h


def timing(h: Harness):
    t = h.ffi.new("sam_i2c_timing_t *")
    assert h.lib.sam_world_i2c_timing(h._w, MASTER, t) == 0
    return t


def busstate(h: Harness) -> int:
    return h.read("SERCOM2.I2CM.STATUS", board=MASTER) >> 4 & 3


def stuck_sda(h: Harness, t0: float, t1: float) -> None:
    """The bus's SDA held low over world time [t0, t1) (seconds from the master's time now)."""
    now = h.now(MASTER)
    assert h.lib.sam_world_fault(h._w, h.lib.SAM_FAULT_STUCK_SDA, -1, now + h.tu(t0), now + h.tu(t1), 0.0, 0) == 0


# (OSC8M prescaler, BAUD, BAUDLOW, SDAHOLD) -> hand-computed: T_LOW = (BAUDLOW or BAUD + 5) / f, T_HIGH = (BAUD + 5) /
# f, f_SCL = 1 / (T_LOW + T_HIGH + 125 ns), setup = T_LOW - hold max - 125 ns; the mode by f_SCL; violated limits
CASES = [
    # 1 MHz, BAUD 0: 5 us each, 98.77 kHz: Standard-mode, within 4.7 / 4.0 us
    ((3, 0, 0, 0), (5e-6, 5e-6, 4.875e-6, "STANDARD", 0)),
    # 1 MHz, BAUD 3, BAUDLOW 0: BAUD times both halves, 8 us each; SDAHOLD 2 holds 600 ns at most
    ((3, 3, 0, 2), (8e-6, 8e-6, 8e-6 - 600e-9 - RISE, "STANDARD", 0)),
    # 8 MHz, BAUD 60, BAUDLOW 30: T_LOW 35/8 = 4.375 us < 4.7 at 79.2 kHz (Standard-mode)
    ((0, 60, 30, 0), (4.375e-6, 8.125e-6, 4.25e-6, "STANDARD", "LOW")),
    # 8 MHz, BAUD 30, BAUDLOW 2: T_LOW 7/8 = 0.875 us < 1.3 at 186 kHz (Fast-mode); T_HIGH 4.375 us
    ((0, 30, 2, 0), (0.875e-6, 4.375e-6, 0.75e-6, "FAST", "LOW")),
    # 8 MHz, BAUD 30, BAUDLOW 1, SDAHOLD 3: T_LOW 0.75 us, SDA changes up to 0.8 us after SCL falls: after it rose
    ((0, 30, 1, 3), (0.75e-6, 4.375e-6, 0.75e-6 - 800e-9 - RISE, "FAST", "LOW SETUP SDA_IN_HIGH")),
]


@pytest.mark.parametrize("regs,want", CASES)
def test_scl_timing_from_baud_baudlow_and_sdahold(regs, want):
    presc, baud, baudlow, sdahold = regs
    t_low, t_high, t_setup, mode, viol = want
    h = bus(baud | baudlow << 8, sdahold, presc, enable=False)
    t = timing(h)
    assert t.f_gclk_hz == 8e6 / 2**presc
    assert t.t_low_s == pytest.approx(t_low) and t.t_high_s == pytest.approx(t_high)
    assert t.f_scl_hz == pytest.approx(1 / (t_low + t_high + RISE))
    assert t.t_setup_s == pytest.approx(t_setup)
    assert t.mode == getattr(h.lib, f"SAM_I2C_{mode}")
    bits = sum(getattr(h.lib, f"SAM_I2C_VIOL_{v}") for v in viol.split()) if viol else 0
    assert t.violations == bits


def test_a_low_phase_under_the_limit_is_not_sampled_the_master_reads_a_nack():
    """Fast-mode with T_LOW 0.875 us (< 1.3 us) and SDA settled in time: the slave cannot be relied on to sample the
    bits: no AMATCH, the master's MB with RXNACK; the note names the limit, once."""
    h = bus(30 | 2 << 8, 0, 0)
    for _ in range(2):
        h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
        h.advance(12 * 5.375e-6 + 10e-6)
        assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB
        assert h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
        assert not h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH
        h.write("SERCOM2.I2CM.CTRLB", CMD_STOP, board=MASTER)
        h.advance(20e-6)
    notes = [n for n in h.notes() if "SCL timing outside" in n]
    assert len(notes) == 1 and "Fast-mode" in notes[0] and "T_LOW 0.875 us < 1.30 us" in notes[0]


def test_sda_changing_while_scl_is_high_is_a_bus_error():
    """SDAHOLD 400-800 ns against a 0.75 us low phase: SDA changes after SCL rose, a false STOP after the START; the
    master sets BUSERR with ARBLOST, MB and ERROR (28.10.8), the bus state BUSY; the slave sees no address."""
    h = bus(30 | 1 << 8, 3, 0)
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    h.advance(12 * 5.25e-6)
    st = h.read("SERCOM2.I2CM.STATUS", board=MASTER)
    assert st & BUSERR and st & ARBLOST and st >> 4 & 3 == BUSY
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & (M_MB | M_ERROR) == M_MB | M_ERROR
    assert not h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH
    h.write("SERCOM2.I2CM.STATUS", BUSERR | ARBLOST, board=MASTER)  # write one to clear
    assert not h.read("SERCOM2.I2CM.STATUS", board=MASTER) & (BUSERR | ARBLOST)


def test_bus_states_unknown_idle_owner_idle_busy_idle():
    """UNKNOWN after enable until forced IDLE; OWNER from the START to the STOP, then IDLE; SDA pulled low while the
    bus is idle is a START by someone else: BUSY, and an ADDR written then waits (no START, no MB); SDA let go is a
    STOP: IDLE, and the waiting START goes out (the slave's AMATCH)."""
    h = bus(force=False)
    assert busstate(h) == UNKNOWN
    h.write("SERCOM2.I2CM.STATUS", IDLE << 4, board=MASTER)
    h.advance(10e-6)
    assert busstate(h) == IDLE
    h.write("SERCOM2.I2CM.ADDR", (ADDR + 1) << 1, board=MASTER)  # nobody answers
    assert busstate(h) == OWNER
    h.advance(12 * T1)
    h.write("SERCOM2.I2CM.CTRLB", CMD_STOP, board=MASTER)
    h.advance(3 * T1)
    assert busstate(h) == IDLE
    stuck_sda(h, 10e-6, 300e-6)
    h.advance(50e-6)
    assert busstate(h) == BUSY
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    h.advance(15 * T1)
    assert busstate(h) == BUSY and not h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB
    assert not h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH
    h.advance(300e-6)
    assert busstate(h) == OWNER
    h.advance(12 * T1)
    assert h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH


def test_sda_stuck_during_a_transaction_loses_arbitration_then_busy_until_the_stop():
    """SDA pulled low while the master sends its address: ARBLOST with MB and ERROR on its next high bit, the bus
    state BUSY (Figure 28-4: lost arbitration) until SDA is let go (a STOP: IDLE); no BUSERR. (An address nobody
    answers: the model sends an address whole, and a slave that matched it would hold SCL, so no STOP.)"""
    h = bus()
    h.write("SERCOM2.I2CM.ADDR", (ADDR + 1) << 1, board=MASTER)
    stuck_sda(h, 3e-6, 200e-6)
    h.advance(4 * T1)
    st = h.read("SERCOM2.I2CM.STATUS", board=MASTER)
    assert st & ARBLOST and not st & BUSERR and st >> 4 & 3 == BUSY
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & (M_MB | M_ERROR) == M_MB | M_ERROR
    h.advance(250e-6)
    assert busstate(h) == IDLE


def test_a_stop_in_the_middle_of_the_masters_transaction_is_a_bus_error():
    """SDA pulled low and let go again within one bit while the master owns the bus: the rising SDA with SCL high is
    a misplaced STOP: BUSERR (with ARBLOST and MB), and the STOP leaves the bus IDLE."""
    h = bus()
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    stuck_sda(h, 2e-6, 5e-6)
    h.advance(4 * T1)
    st = h.read("SERCOM2.I2CM.STATUS", board=MASTER)
    assert st & BUSERR and st & ARBLOST and st >> 4 & 3 == IDLE
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB


def first_time(h: Harness, cond, step: float, limit: float) -> int:
    """The master's time (tu) at the check that first finds cond(h), stepping the world by `step` seconds between
    checks."""
    t_end = h.now(MASTER) + h.tu(limit)
    while h.now(MASTER) < t_end:
        t = h.now(MASTER)
        if cond(h):
            return t
        h.advance(step)
    raise AssertionError("never held")


@pytest.mark.parametrize("inactout, periods", [(1, 5), (2, 10), (3, 20)])
def test_the_inactive_bus_time_out_gives_the_bus_up_after_its_scl_periods(inactout, periods):
    """DS40001882 28.6.2.4.3 / 28.8.1 CTRLA.INACTOUT: while the addressed slave holds SCL low (its software has not
    answered AMATCH), the master that owns the bus counts the bus inactive and, after INACTOUT's SCL periods (5, 10 or
    20 of its own), gives it up: the bus state goes from OWNER to IDLE. Measured from the slave's AMATCH (the start
    of its hold), to half a period's steps: within one period of the count."""
    h = bus(inactout=inactout)
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    t_match = first_time(h, lambda h: h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH, T1 / 2, 20 * T1)
    seen = []
    t_idle = first_time(h, lambda h: seen.append(busstate(h)) or seen[-1] == IDLE, T1 / 2, 40 * T1)
    assert set(seen[:-1]) == {OWNER}  # the master's until then
    assert periods * h.tu(T1) <= t_idle - t_match < (periods + 0.9) * h.tu(T1), (t_idle - t_match) / h.tu(T1)


def test_without_the_time_out_the_master_keeps_the_bus_while_the_slave_holds_scl():
    """INACTOUT 0 (off): the slave's hold lasts as long as its software lets it; the master stays OWNER."""
    h = bus()
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    h.advance(12 * T1)
    assert h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH
    h.advance(60 * T1)
    assert busstate(h) == OWNER


def test_polling_the_slave_finer_than_a_bit_does_not_stall_the_world():
    """Harness accesses run one board on alone, a few microseconds of its time each (here at 1 MHz): the slave polled
    every eighth of an SCL period ran past the time of the address byte the master then sent it, and the world,
    waiting for the slave's answer to a step it never took, stopped with "the boards wait for each other". The step
    is taken as the board's next block would take it; the match and the hold follow, and the time-out after it."""
    h = bus(inactout=1)
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    t_match = first_time(h, lambda h: h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH, T1 / 8, 20 * T1)
    t_idle = first_time(h, lambda h: busstate(h) == IDLE, T1 / 8, 40 * T1)
    assert 4 * h.tu(T1) <= t_idle - t_match <= 7 * h.tu(T1)
