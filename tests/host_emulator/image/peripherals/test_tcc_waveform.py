"""TCC0's waveform on the register-level harness: the counter's phase after enable, each output's high time over any
interval against an independent tick-by-tick reference, PER written while counting, PERB and LUPD, and what the plant
sees through the waveform path and the motors' electrical model (DS40001882 chapter 31, TCC)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.image import board as wiring
from host_emulator.image.harness import Harness

from .bench import GCLK_TCC0_TCC1, TU_PER_US_AT_1MHZ, bus_clock, gclk_channel, pmux, tcc_count

CTRLA_ENABLE = 1 << 1
PRESCALER_POS = 8
PRESCALERS = (1, 2, 4, 8, 16, 64, 256, 1024)  # CTRLA.PRESCALER 0..7 (31.8.1 CTRLA)
WAVE_NPWM = 0x2
CTRLB_LUPD = 1 << 1
STATUS_PERBV = 1 << 7
SYNCBUSY_ENABLE = 1 << 1
MAX24 = 0xFFFFFF
EN_ALPHA = wiring.pin_number(wiring.CELL_WIRING["en_alpha"])  # PA10: TCC0/WO2 on PMUX F
PH_ALPHA = wiring.pin_number(wiring.CELL_WIRING["ph_alpha"])
NSLEEP = wiring.pin_number(wiring.CELL_WIRING["nsleep"])


def pwm(per: int, cc2: int, presc: int = 1, *, window_s: float = 1e-3, **kw) -> tuple[Harness, int]:
    """TCC0 from GCLK0 (1 MHz after reset) / presc counting 0..per, WO2 = CC[2] on the alpha driver's EN (awake, PH
    high); returns the harness and the time of the enabling write (tu)."""
    h = Harness(window_s=window_s, **kw)
    h.write("PORT.Group[0].DIRSET", 1 << NSLEEP | 1 << PH_ALPHA)
    h.write("PORT.Group[0].OUTSET", 1 << NSLEEP | 1 << PH_ALPHA)
    bus_clock(h, "TCC0")
    gclk_channel(h, GCLK_TCC0_TCC1)
    h.write("TCC0.WAVE", WAVE_NPWM)
    h.write("TCC0.PER", per)
    h.write("TCC0.CC[2]", cc2)
    pmux(h, EN_ALPHA, "F")
    h.write("TCC0.CTRLA", CTRLA_ENABLE | PRESCALERS.index(presc) << PRESCALER_POS)
    return h, h.t_access


def reference_high(t_start: int, tick: int, per: int, cc: int, t0: int, t1: int) -> int:
    """High time of an NPWM output over [t0, t1), count by count: the counter is k mod (per + 1) over
    [t_start + k tick, t_start + (k + 1) tick), the output high while the count is below cc (31.6.2.5.2)."""
    hi = 0
    for k in range(max(0, (t0 - t_start) // tick), (t1 - t_start + tick - 1) // tick):
        if k % (per + 1) < cc:
            a, b = t_start + k * tick, t_start + (k + 1) * tick
            hi += max(0, min(b, t1) - max(a, t0))
    return hi


def test_the_counter_starts_from_zero_when_the_enable_has_synchronised():
    """DS40001882 31.6.2.1 and 31.8.2 SYNCBUSY: the counter starts once CTRLA.ENABLE has synchronised (SYNCBUSY.ENABLE
    clears); COUNT then advances one per prescaled GCLK cycle and wraps after PER (31.8.16 COUNT; read through the
    READSYNC command, 31.8.3, as the count when the command was carried out)."""
    per, presc = 99, 4
    h, t_en = pwm(per, 30, presc)
    assert not h.read("TCC0.SYNCBUSY") & SYNCBUSY_ENABLE  # the harness's next access comes after 3 GCLK cycles
    t_clear = h.t_access
    info = h.tcc_info()
    tick = presc * TU_PER_US_AT_1MHZ
    assert info.running and info.tick_tu == tick and info.prescaler == presc
    assert t_en < info.cycle_start_tu <= t_clear
    assert info.period_tu == (per + 1) * tick
    t_start = int(info.cycle_start_tu)
    for dt_us in (3, 97, 401, 1234, 5077):
        h.advance_to(t_start + dt_us * TU_PER_US_AT_1MHZ)
        c, t = tcc_count(h)
        assert c == (t - t_start) // tick % (per + 1)


@settings(max_examples=40, deadline=None)
@given(
    presc=st.sampled_from(PRESCALERS[:6]),
    per=st.integers(1, 300),
    cc_frac=st.floats(0.0, 1.02),
    start=st.floats(0.0, 3.0),
    length=st.floats(0.0, 3.5),
)
def test_the_high_time_over_any_interval_is_the_waveforms(presc, per, cc_frac, start, length):
    """Over any interval (in periods: partial ones at both ends), the model's high time of WO2 equals an independent
    count-by-count reference of the NPWM waveform, for any prescaler, PER and CC (CC > PER: always high)."""
    cc = round(cc_frac * (per + 1))
    h, _ = pwm(per, cc, presc, window_s=1e-3)
    h.advance(50e-6)
    info = h.tcc_info()
    t_start, tick, period = int(info.cycle_start_tu), int(info.tick_tu), int(info.period_tu)
    t0 = t_start + int(start * period)
    t1 = t0 + int(length * period)
    h.advance_to(max(t1, h.now()) + 1)
    assert h.tcc_high(2, t0, t1) == reference_high(t_start, tick, per, cc, t0, t1)


def buffer_taken_at(t_write: int, t_start: int, tick: int, period: int) -> int:
    """When a buffered CC written at t_write takes over (DS40001882 31.6.2.6): valid once its write has synchronised
    (3 GCLK cycles, SYNCBUSY.CCBn; a count each here), copied at the first wrap after that."""
    ready = t_write + 3 * tick
    return t_start + ((ready - t_start) // period + 1) * period


@settings(max_examples=40, deadline=None)
@given(
    per=st.integers(19, 300),
    cc_frac=st.floats(0.0, 1.02),
    cc2_frac=st.floats(0.0, 1.02),
    start=st.floats(-4.0, 3.0),
    length=st.floats(0.0, 3.5),
    buffered=st.booleans(),
)
def test_the_mean_path_over_any_interval_is_the_duty_times_its_time(per, cc_frac, cc2_frac, start, length, buffered):
    """The mean path's figure over any interval (before the counter starts, across a buffered CC change or not):
    min(CC, PER + 1) / (PER + 1) of the time the counter runs in it, stretch by stretch, against a reference that
    knows only the counter's start and the UPDATE that takes the buffer over (the first wrap after the write has
    synchronised, DS40001882 31.6.2.6)."""
    cc, cc2 = round(cc_frac * (per + 1)), round(cc2_frac * (per + 1))
    h, t_enable = pwm(per, cc, window_s=1e-3)
    h.advance(10e-6)  # the enable synchronised (3 GCLK cycles), the first cycle (>= 20 us) not over
    info = h.tcc_info()
    t_start, tick, period = int(info.cycle_start_tu), int(info.tick_tu), int(info.period_tu)
    assert t_enable < t_start < h.now()
    h.advance(50e-6)
    t_upd = None
    if buffered:
        h.write("TCC0.CCB[2]", cc2)
        t_upd = buffer_taken_at(h.t_access, t_start, tick, period)
    t0 = max(0, h.now() + int(start * period))
    t1 = t0 + int(length * period)
    hi, den, other = h.tcc_mean(2, t0, t1)

    def duty_time(c: int, a: int, b: int) -> int:
        return min(c, per + 1) * max(0, b - max(a, t_start))

    if t_upd is None or t1 <= t_upd:
        want = duty_time(cc, t0, t1)
    else:
        want = duty_time(cc, t0, max(t0, t_upd)) + duty_time(cc2, max(t0, t_upd), t1)
    assert (hi, other) == (want, 0.0)
    assert den == (per + 1 if t1 > t0 else 1)  # (an empty interval: no period to speak of)


@pytest.mark.parametrize("ticks_before", range(8))
def test_a_buffered_cc_written_near_a_wrap_is_taken_at_the_first_wrap_after_its_sync(ticks_before):
    """The edge the random intervals above rarely reach: CCB written a few counts before a wrap. It is valid once its
    write has synchronised (3 GCLK cycles) and taken at the first wrap after that (DS40001882 31.6.2.6): at the wrap
    ahead when it is ready before it, at the one after when it is ready at or past it. The mean path's figure over
    two periods each side of the wrap follows, written at eight phases a count apart."""
    per, cc, cc2 = 39, 10, 30
    h, _ = pwm(per, cc, window_s=1e-3)
    h.advance(10e-6)
    info = h.tcc_info()
    t_start, tick, period = int(info.cycle_start_tu), int(info.tick_tu), int(info.period_tu)
    wrap = t_start + ((h.now() - t_start) // period + 3) * period
    h.advance_to(wrap - (ticks_before + 1) * tick)
    h.write("TCC0.CCB[2]", cc2)
    t_upd = buffer_taken_at(h.t_access, t_start, tick, period)
    t0, t1 = wrap - 2 * period, wrap + 2 * period
    assert h.tcc_mean(2, t0, t1) == (cc * (t_upd - t0) + cc2 * (t1 - t_upd), per + 1, 0.0)


def test_the_plant_sees_the_waveform_path_high_time_and_the_mean_path_the_mean():
    """One plant window of 0.37 PWM periods: the waveform path gives the driver the window's real high time (all
    or nothing in a window inside the high or the low part), the mean path CC / (PER + 1) whatever the phase."""
    per, cc = 999, 250  # 1 ms periods at 1 MHz, high for the first 250 us
    for path in ("waveform", "mean"):
        h, _ = pwm(per, cc, window_s=370e-6, pwm=path)
        h.advance(20e-6)
        w = h.tu(370e-6)
        t_start = int(h.tcc_info().cycle_start_tu)
        for k in range(3, 12):
            h.advance_to((k + 1) * w + 1)
            volt, awake = h.motor(0)
            assert awake == 1.0
            want = reference_high(t_start, TU_PER_US_AT_1MHZ, per, cc, k * w, (k + 1) * w) / w
            if path == "mean":
                want = cc / (per + 1)
            assert volt / h.params.supply_v == pytest.approx(want, abs=1e-12), (path, k)


def test_register_reads_inside_a_window_change_nothing_the_plant_sees():
    """COUNT, STATUS and CC reads move the model's idea of the current cycle on; the windows' high times (the waveform
    path, with a buffered change in flight) are the same with them as without, to the bit."""
    runs = []
    for reads in (False, True):
        h, _ = pwm(99, 30, 2, window_s=270e-6, pwm="waveform")
        h.advance(20e-6)
        w = h.tu(270e-6)
        seen = []
        for k in range(2, 14):
            if k == 6:
                h.write("TCC0.CCB[2]", 70)
            if reads:
                for frac in (0.13, 0.58, 0.91):
                    h.advance_to(k * w + int(frac * w))
                    tcc_count(h)
                    h.read("TCC0.STATUS")
                    h.read("TCC0.CC[2]")
            h.advance_to((k + 1) * w + 1)
            seen.append(h.motor(0))
        runs.append(seen)
    assert runs[0] == runs[1]
    assert len({v for v, _ in runs[0]}) > 2  # the windows saw different parts of the waveform


def window_duties(presc: int, path: str, n: int = 80) -> list[float]:
    h, _ = pwm(49, 20, presc, window_s=50e-6, pwm=path)  # 50 us periods at DIV1 (the cell's 20 kHz), 40 % duty
    h.advance(100e-6)
    out = []
    for _ in range(n):
        h.advance(50e-6)
        out.append(h.motor(0)[0] / h.params.supply_v)
    return out


def test_paths_agree_at_one_period_per_window_and_differ_at_div64():
    """The plant window holds one whole PWM period (the cell's 20 kHz against the 50 us window): every window sees
    exactly CC / (PER + 1) on both paths. At DIV64 the period is 64 windows long: the mean path still sees 40 % in
    every window, the waveform path the drive itself, on (1.0) for 26 windows and off (0.0) for the rest."""
    for path in ("mean", "waveform"):
        assert window_duties(1, path) == pytest.approx([0.4] * 80, abs=1e-12)
    assert window_duties(64, "mean") == pytest.approx([0.4] * 80, abs=1e-12)
    slow = window_duties(64, "waveform", 128)
    assert min(slow) == 0.0 and max(slow) == 1.0
    assert sum(slow) == pytest.approx(0.4 * 128, abs=1.0)


def test_per_written_while_counting_takes_effect_at_once():
    """DS40001882 31.6.2.6 (Figure 31-9, unbuffered update): PER may be written while the counter runs; a new TOP above
    the count changes the current period; below the count the counter runs on to MAX before it wraps. Neither stops
    the board (silicon allows both)."""
    h, _ = pwm(999, 250)
    h.advance(2.3e-3)
    h.write("TCC0.PER", 1499)
    c, t = tcc_count(h)  # synchronised 3 GCLK cycles after its command: probes leave room for that
    assert c < 1000, "the write came while the count was below the new TOP"
    info = h.tcc_info()
    assert info.per == 1499 and info.top == 1499
    t_wrap = t + (1500 - c) * TU_PER_US_AT_1MHZ
    h.advance_to(t_wrap - 20 * TU_PER_US_AT_1MHZ)
    assert tcc_count(h)[0] > 999, "the counter passed the old TOP"
    h.advance_to(t_wrap + 1 * TU_PER_US_AT_1MHZ)
    assert tcc_count(h)[0] < 10
    # a TOP below the count: on to MAX (24 bits), not wrapped at the new TOP
    h.advance_to(h.t_access + 800 * TU_PER_US_AT_1MHZ)
    assert tcc_count(h)[0] > 400
    h.write("TCC0.PER", 399)
    info = h.tcc_info()
    assert info.top == MAX24 and h.error() is None
    h.advance(2e-3)
    assert tcc_count(h)[0] > 2000


def test_perb_under_lock_update_waits_and_clearing_it_copies_at_the_next_update():
    """DS40001882 31.6.2.6 Double Buffering, 31.8.3 CTRLBSET.LUPD and 31.8.13 STATUS.PERBV: PERB written under LUPD
    stays in the buffer across UPDATEs (PERBV set); cleared, it is copied on the next UPDATE, not at once."""
    h, _ = pwm(999, 250)
    h.advance(1.5e-3)
    h.write("TCC0.CTRLBSET", CTRLB_LUPD)
    h.write("TCC0.PERB", 499)
    h.advance(2.5e-3)
    assert h.read("TCC0.PER") == 999 and h.read("TCC0.STATUS") & STATUS_PERBV
    h.write("TCC0.CTRLBCLR", CTRLB_LUPD)
    c, t = tcc_count(h)
    assert h.read("TCC0.PER") == 999
    h.advance_to(t + (1000 - c + 3) * TU_PER_US_AT_1MHZ)
    assert h.read("TCC0.PER") == 499 and not h.read("TCC0.STATUS") & STATUS_PERBV
    assert h.tcc_info().period_tu == 500 * TU_PER_US_AT_1MHZ


def mean_current(h: Harness) -> float:
    """The last window's mean current times R over the supply: the plant's drive term awake x (volt - back-EMF)."""
    volt, awake = h.motor(0)
    return volt * awake / h.params.supply_v


@pytest.mark.parametrize("lupd", [False, True])
def test_the_high_time_across_a_buffered_period_and_compare_change(lupd):
    """DS40001882 31.6.2.6 Double Buffering: PERB and CCB written in one cycle take over together at the next UPDATE
    (with LUPD set meanwhile: at the first UPDATE after it clears); the high time over an interval holding that
    UPDATE is the old waveform's up to it and the new one's from it, each count by count."""
    tick = TU_PER_US_AT_1MHZ
    h, _ = pwm(199, 50)
    h.advance(10e-6)
    t_start = int(h.tcc_info().cycle_start_tu)
    h.advance(1.03e-3)
    if lupd:
        h.write("TCC0.CTRLBSET", CTRLB_LUPD)
    h.write("TCC0.PERB", 299)
    h.write("TCC0.CCB[2]", 260)
    if lupd:
        h.advance(0.5e-3)  # two UPDATEs pass
        assert h.tcc_info().per == 199
        h.write("TCC0.CTRLBCLR", CTRLB_LUPD)
    c, t = tcc_count(h)
    t_upd = t + (200 - c) * tick
    assert (t_upd - t_start) % (200 * tick) == 0
    t0, t1 = t_upd - 137 * tick - 555, t_upd + 1000 * tick + 77
    h.advance_to(t1 + 1)
    info = h.tcc_info()
    assert (info.per, info.cc[2]) == (299, 260)
    want = reference_high(t_start, tick, 199, 50, t0, t_upd) + reference_high(t_upd, tick, 299, 260, t_upd, t1)
    assert h.tcc_high(2, t0, t1) == want


def test_the_motor_current_follows_each_pulse_with_the_electrical_time_constant():
    """With tau_e = L / R the plant sees R times the window's mean current (the motor at rest: no back-EMF). At DIV64
    the current rises through the first windows of a pulse: from 0 at the rising edge, Vs (1 - exp(-t/tau)),
    integrated over each window; at the cell's 20 kHz every window sees the duty, the current's ripple averaging out
    over each whole period (its periodic steady state)."""
    tau, w_s = 36e-6, 50e-6
    h, _ = pwm(49, 20, 64, window_s=w_s, pwm="waveform", motor_tau_s=tau)
    h.advance(10e-6)
    t_on, w = int(h.tcc_info().cycle_start_tu), h.tu(w_s)  # the first pulse rises as the counter starts
    k = t_on // w  # the window holding the rise
    h.advance_to((k + 1) * w + 1)
    d = ((k + 1) * w - t_on) / h.tu_hz  # the pulse's part of that window, s
    assert mean_current(h) == pytest.approx((d - tau * -math.expm1(-d / tau)) / w_s, rel=1e-9)
    j1 = -math.expm1(-d / tau)  # the current (x R / Vs) at the window's end
    h.advance_to((k + 2) * w + 1)
    assert mean_current(h) == pytest.approx(1 - (1 - j1) * tau / w_s * -math.expm1(-w_s / tau))
    h.advance_to((k + 8) * w + 1)
    assert mean_current(h) == pytest.approx(1.0, abs=1e-3)
    fast, _ = pwm(49, 20, 1, window_s=w_s, pwm="waveform", motor_tau_s=tau)
    fast.advance(2e-3)  # the current's periodic steady state (40 time constants)
    for _ in range(10):
        fast.advance(w_s)
        assert fast.motor(0)[0] / fast.params.supply_v == pytest.approx(0.4, abs=1e-9)


def test_the_electrical_model_needs_the_waveform_path():
    with pytest.raises(ValueError, match="needs pwm = 'waveform'"):
        Harness(motor_tau_s=36e-6)
    with pytest.raises(ValueError, match="pwm = 'edges'"):
        Harness(pwm="edges")
