"""TCC0 in normal PWM on the register-level harness: the period, the compare value, the double-buffered compare
taking over at the period's end, and the duty the plant sees on a cell's driver, against the SAMD21 datasheet
(Microchip DS40001882, chapter 31 "TCC - Timer/Counter for Control Applications")."""

from __future__ import annotations

import pytest

from host_emulator.image import board as wiring
from host_emulator.image.harness import Harness

from .bench import GCLK_TCC0_TCC1, TU_PER_US_AT_1MHZ, bus_clock, gclk_channel, pmux, tcc_count

TICK = TU_PER_US_AT_1MHZ  # TCC0 on GCLK0 (1 MHz), prescaler DIV1
PER = 999  # 1 ms periods
WINDOW_S = 1e-3  # the plant's window: one PWM period
CTRLA_ENABLE = 1 << 1
WAVE_NPWM = 0x2
CTRLB_LUPD = 1 << 1
STATUS_CCBV2 = 1 << 18
EN_ALPHA = wiring.pin_number(wiring.CELL_WIRING["en_alpha"])  # PA10: TCC0/WO2 on PMUX F
PH_ALPHA = wiring.pin_number(wiring.CELL_WIRING["ph_alpha"])
NSLEEP = wiring.pin_number(wiring.CELL_WIRING["nsleep"])


def pwm(cc2: int) -> Harness:
    """TCC0 counting 0..PER on WO2 (CC[2]), routed to the alpha driver's EN; the driver awake, PH high."""
    h = Harness(window_s=WINDOW_S)
    h.write("PORT.Group[0].DIRSET", 1 << NSLEEP | 1 << PH_ALPHA)
    h.write("PORT.Group[0].OUTSET", 1 << NSLEEP | 1 << PH_ALPHA)
    bus_clock(h, "TCC0")
    gclk_channel(h, GCLK_TCC0_TCC1)
    h.write("TCC0.WAVE", WAVE_NPWM)
    h.write("TCC0.PER", PER)
    h.write("TCC0.CC[2]", cc2)
    pmux(h, EN_ALPHA, "F")
    h.write("TCC0.CTRLA", CTRLA_ENABLE)
    h.advance(20e-6)
    return h


def next_update(h: Harness) -> int:
    """When the counter next wraps (the UPDATE condition), from COUNT (31.8.16) synchronised by READSYNC (31.8.3)."""
    c, t = tcc_count(h)
    return t + (PER + 1 - c) * TICK


def window_of(h: Harness, t: int) -> tuple[int, int]:
    w = h.tu(WINDOW_S)
    return t // w * w, t // w * w + w


def duty(h: Harness) -> float:
    volt, awake = h.motor(0)
    assert awake == 1.0
    return volt / h.params.supply_v


def test_normal_pwm_drives_cc_over_per_plus_one_of_each_period_to_the_driver():
    """DS40001882 31.6.2.5.2 Normal Pulse-Width Modulation (NPWM): the output is set at the start of the period
    (PER + 1 counts) and cleared when the counter matches CC; routed to the pin by PMUX F (7.1 Multiplexed
    Signals: PA10 is TCC0/WO[2]); the plant sees the mean, CC / (PER + 1) of the supply."""
    h = pwm(250)
    h.advance(3e-3)
    assert duty(h) == pytest.approx(250 / (PER + 1), abs=1e-12)
    assert h.pin_state(EN_ALPHA).function == 5  # F


def test_a_buffered_compare_value_takes_effect_at_the_period_boundary_not_before():
    """DS40001882 31.6.2.6 Double Buffering: a value written to CCBx is copied to CCx on the UPDATE condition
    (the counter's wrap at the end of the period), not at the write; STATUS.CCBVx is set while the buffer holds a
    value not yet copied (31.8.13 STATUS)."""
    h = pwm(250)
    h.advance(2.3e-3)
    h.write("TCC0.CCB[2]", 750)
    t_write = h.t_access
    assert h.read("TCC0.CC[2]") == 250, "CCB must not take effect at the write"
    assert h.read("TCC0.STATUS") & STATUS_CCBV2
    t_upd = next_update(h)
    assert t_write < t_upd <= t_write + (PER + 1) * TICK
    h.advance_to(t_upd - 30 * TICK)
    assert h.read("TCC0.CC[2]") == 250, "still the old compare value before the boundary"
    h.advance_to(t_upd + 5 * TICK)
    assert h.read("TCC0.CC[2]") == 750
    assert not h.read("TCC0.STATUS") & STATUS_CCBV2


def buffered_duty_change(read_after_update: bool) -> None:
    h = pwm(250)
    h.advance(2.3e-3)
    t_upd = next_update(h)
    h.write("TCC0.CCB[2]", 750)
    w0, w1 = window_of(h, t_upd)
    if read_after_update:  # any read of a TCC0 register after the UPDATE, before the window ends
        h.advance_to(t_upd + 5 * TICK)
        h.read("TCC0.SYNCBUSY")
    h.advance_to(w1 + 1)
    expect = (250 * (t_upd - w0) + 750 * (w1 - t_upd)) / ((PER + 1) * (w1 - w0))
    assert duty(h) == pytest.approx(expect, abs=1e-12)
    h.advance_to(w1 + h.tu(WINDOW_S) + 1)
    assert duty(h) == pytest.approx(750 / (PER + 1), abs=1e-12)


def test_the_plant_sees_the_old_duty_up_to_the_boundary_and_the_new_one_after():
    """DS40001882 31.6.2.6 Double Buffering with 31.6.2.5.2 NPWM: the period in which CCB was written keeps the
    old duty to its end; the plant's window holding the boundary sees each part for its own time."""
    buffered_duty_change(read_after_update=False)


def test_a_register_read_after_the_boundary_does_not_move_the_duty_change():
    """DS40001882 31.6.2.6 Double Buffering: the copy happens at the UPDATE condition, whatever the CPU reads
    afterwards; reading SYNCBUSY after the boundary must not change what the output did before it."""
    buffered_duty_change(read_after_update=True)


def test_lock_update_holds_the_buffer_across_the_boundary():
    """DS40001882 31.6.2.6 Double Buffering and 31.8.3 CTRLBSET.LUPD: while Lock Update is set, the buffer is not
    copied on the UPDATE condition."""
    h = pwm(250)
    h.write("TCC0.CTRLBSET", CTRLB_LUPD)
    h.write("TCC0.CCB[2]", 600)
    h.advance(2.5e-3)
    assert h.read("TCC0.CC[2]") == 250


def test_clearing_lock_update_copies_the_buffer_at_the_next_boundary():
    """DS40001882 31.6.2.6 Double Buffering: when CTRLB.LUPD is cleared, the buffer values (CCBV set) are copied
    on the next UPDATE condition."""
    h = pwm(250)
    h.write("TCC0.CTRLBSET", CTRLB_LUPD)
    h.write("TCC0.CCB[2]", 600)
    assert h.read("TCC0.STATUS") & STATUS_CCBV2
    h.write("TCC0.CTRLBCLR", CTRLB_LUPD)
    h.advance(2.5e-3)
    assert h.read("TCC0.CC[2]") == 600


def test_a_buffered_period_takes_effect_at_the_period_boundary():
    """DS40001882 31.6.2.6 Double Buffering: PERB is copied to PER on the UPDATE condition."""
    h = pwm(250)
    h.write("TCC0.PERB", 499)
    assert h.read("TCC0.PER") == PER
    h.advance(2.5e-3)
    assert h.read("TCC0.PER") == 499
