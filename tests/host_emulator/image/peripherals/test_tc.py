"""TC3 in 16-bit match-frequency mode on the register-level harness: period, count, flags and their interrupt,
against the SAMD21 datasheet (Microchip DS40001882, chapter 30 "TC - Timer/Counter")."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness

from .bench import GCLK_TCC2_TC3, TU_PER_US_AT_1MHZ, bus_clock, gclk_channel

TICK = TU_PER_US_AT_1MHZ  # TC3 on GCLK0 (1 MHz), prescaler DIV1
CTRLA_ENABLE = 1 << 1
CTRLA_MFRQ = 1 << 5  # WAVEGEN = MFRQ; MODE = COUNT16 (0)
OVF, MC0 = 1 << 0, 1 << 4
READREQ_COUNT_CONTINUOUS = 1 << 15 | 1 << 14 | 0x10  # RREQ, RCONT, ADDR = COUNT's offset


def count_synchronised(h: Harness) -> None:
    """COUNT synchronised continuously (30.10.2 READREQ: RREQ with RCONT, ADDR = COUNT), so its reads are live."""
    h.write("TC3.COUNT16.READREQ", READREQ_COUNT_CONTINUOUS)
    h.advance(20e-6)  # the read synchronisation completes (3 GCLK cycles)


def started(cc0: int) -> Harness:
    h = Harness()
    bus_clock(h, "TC3")
    gclk_channel(h, GCLK_TCC2_TC3)
    h.write("TC3.COUNT16.CC[0]", cc0)
    h.write("TC3.COUNT16.CTRLA", CTRLA_MFRQ | CTRLA_ENABLE)
    h.advance(20e-6)  # the enable synchronises (30.6.6 Synchronization)
    count_synchronised(h)
    return h


def next_wrap(h: Harness, cc0: int) -> int:
    """The time (tu) the counter next wraps, from a COUNT read: it counts CC0 + 1 ticks per period."""
    c = h.read("TC3.COUNT16.COUNT")
    return h.t_access + (cc0 + 1 - c) * TICK


def test_the_count_runs_from_zero_to_cc0_and_wraps_with_ovf_and_mc0():
    """DS40001882 30.6.2.5.1 Waveform Output Operations, "Match Frequency (MFRQ)": the counter counts up to CC0
    (the period is CC0 + 1 ticks), is cleared on the match and sets INTFLAG.OVF and MC0 (30.8.12 INTFLAG);
    30.6.2.3 Counter Mode: COUNT reads the running count (synchronised continuously, 30.10.2 READREQ.RCONT)."""
    cc0 = 199
    h = started(cc0)
    h.write("TC3.COUNT16.INTFLAG", OVF | MC0)
    c0 = h.read("TC3.COUNT16.COUNT")
    t0 = h.t_access
    h.advance(50e-6)
    c1 = h.read("TC3.COUNT16.COUNT")
    assert 0 <= c0 <= cc0 and (c1 - c0) % (cc0 + 1) == (h.t_access - t0) // TICK  # one count per microsecond
    wrap = next_wrap(h, cc0)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == 0
    h.advance_to(wrap - 20 * TICK)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == 0, "no flag before the count reaches CC0"
    h.advance_to(wrap + 2 * TICK)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == OVF | MC0
    assert h.read("TC3.COUNT16.COUNT") < 20, "cleared at the match, counting again from zero"
    # the next period is CC0 + 1 ticks long
    assert next_wrap(h, cc0) == wrap + (cc0 + 1) * TICK


def test_the_counter_starts_from_count_at_the_enable_with_no_flag():
    """DS40001882 30.6.2.1 Initialization / 30.6.2.3 Counter Mode: once enabled (CTRLA.ENABLE synchronised,
    30.6.6) the counter counts up from COUNT (zero after reset); OVF is set only when it wraps, CC0 + 1 ticks on."""
    h = Harness()
    bus_clock(h, "TC3")
    gclk_channel(h, GCLK_TCC2_TC3)
    h.write("TC3.COUNT16.CC[0]", 999)
    h.write("TC3.COUNT16.CTRLA", CTRLA_MFRQ | CTRLA_ENABLE)
    t_enable = h.t_access
    h.advance(20e-6)
    count_synchronised(h)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == 0
    assert h.read("TC3.COUNT16.COUNT") <= (h.t_access - t_enable) // TICK


def test_intflag_is_write_one_to_clear_bit_by_bit():
    """DS40001882 30.8.12 INTFLAG: "Writing a zero to this bit has no effect. Writing a one to this bit will clear
    the corresponding interrupt flag." """
    h = started(99)
    h.write("TC3.COUNT16.INTFLAG", OVF | MC0)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == 0
    h.advance(150e-6)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == OVF | MC0
    h.write("TC3.COUNT16.INTFLAG", 0)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == OVF | MC0
    h.write("TC3.COUNT16.INTFLAG", OVF)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == MC0
    h.write("TC3.COUNT16.INTFLAG", MC0)
    assert h.read("TC3.COUNT16.INTFLAG") & (OVF | MC0) == 0


def test_an_enabled_flag_requests_the_tc3_interrupt_and_clearing_it_withdraws_the_request():
    """DS40001882 30.6.4 Interrupts: an interrupt request is generated when a flag is set and its INTENSET bit is
    one, until the flag is cleared; 11.2.2 Interrupt Line Mapping: TC3 is NVIC line 18. The NVIC keeps the
    interrupt pending (ARMv6-M), and ICPR clears it once the request is gone."""
    h = started(99)
    irq = h.irq("TC3")
    assert irq == 18
    h.write("TC3.COUNT16.INTFLAG", OVF | MC0)
    h.write("NVIC.ICPR[0]", 1 << irq)
    h.write("TC3.COUNT16.INTENSET", OVF)
    assert irq not in h.pending()
    h.advance(150e-6)
    assert irq in h.pending()
    assert h.nvic().level >> irq & 1
    h.write("TC3.COUNT16.INTFLAG", OVF)
    assert not h.nvic().level >> irq & 1
    h.write("NVIC.ICPR[0]", 1 << irq)
    assert irq not in h.pending()


def test_the_flag_of_a_disabled_interrupt_requests_nothing():
    """DS40001882 30.8.8 INTENCLR / 30.8.9 INTENSET: a flag whose interrupt is not enabled raises no request."""
    h = started(99)
    h.write("TC3.COUNT16.INTENSET", MC0)
    h.write("TC3.COUNT16.INTENCLR", MC0)
    h.write("TC3.COUNT16.INTFLAG", OVF | MC0)
    h.write("NVIC.ICPR[0]", 1 << h.irq("TC3"))
    h.advance(250e-6)
    assert h.read("TC3.COUNT16.INTFLAG") & OVF
    assert h.irq("TC3") not in h.pending()


def test_an_access_with_the_bus_clock_off_stops_the_board_naming_it():
    """DS40001882 16.6.2.6 (PM APB clock masks): a peripheral's registers are reachable only while its APB clock is
    enabled; the model makes the access an error naming it rather than a silent zero."""
    h = Harness()
    with pytest.raises(RuntimeError, match="TC3.*bus clock is off"):
        h.write("TC3.COUNT16.CC[0]", 1)
