"""PORT writes as the cell's motor driver and the EIC see them on the register-level harness: a write that changes a
bit (a toggle, a pull in PINCFG alone, OUTSET of a pull's direction) reaches them at its time; one that changes no
register byte (the PORT model's fast path, csrc/sam_port.c) leaves the plant's drive bit for bit as without it."""

from __future__ import annotations

import pytest

from host_emulator.image import board as wiring
from host_emulator.image.harness import Harness

from .bench import GCLK_EIC, GCLK_TCC0_TCC1, bus_clock, gclk_channel, pmux

G = "PORT.Group[0]"
EN = wiring.pin_number(wiring.CELL_WIRING["en_alpha"])  # PA10: TCC0/WO2 on PMUX F
PH = wiring.pin_number(wiring.CELL_WIRING["ph_alpha"])
NSLEEP = wiring.pin_number(wiring.CELL_WIRING["nsleep"])
WINDOW_S = 1e-3
PINCFG_PMUXEN, PINCFG_INEN, PINCFG_PULLEN = 0x01, 0x02, 0x04  # DS40001882 23.8.14 PINCFG
FREE = 14  # PA14: not wired on a cell


def drive(h: Harness) -> float:
    """The alpha driver's mean voltage over the last window, as a fraction of the supply (awake all of it)."""
    volt, awake = h.motor(0)
    assert awake == 1.0
    return volt / h.params.supply_v


def window_after(h: Harness) -> tuple[int, int]:
    """The plant window after the one holding the board's time now."""
    w = h.tu(WINDOW_S)
    w0 = (h.now() // w + 1) * w
    return w0, w0 + w


def gpio_driver(ph_out: bool) -> Harness:
    """NSLEEP and EN GPIO outputs high; PH a GPIO output high (ph_out) or an input with OUT set and no pull."""
    h = Harness(window_s=WINDOW_S)
    h.write(f"{G}.DIRSET", 1 << NSLEEP | 1 << EN | (1 << PH if ph_out else 0))
    h.write(f"{G}.OUTSET", 1 << NSLEEP | 1 << EN | 1 << PH)
    return h


def test_a_toggle_of_ph_reaches_the_driver_at_its_time():
    """DS40001882 23.8.8 OUTTGL: writing one toggles that bit of OUT; the DRV8874's PH input follows the pin from
    then on, so the window holding the toggle sees the supply with one sign before it and the other after."""
    h = gpio_driver(ph_out=True)
    w0, w1 = window_after(h)
    h.advance_to(w0 + (w1 - w0) // 4)
    h.write(f"{G}.OUTTGL", 1 << PH)
    t = h.t_access
    assert h.pin_state(PH).level == 0
    h.advance_to(w1 + 1)
    assert drive(h) == pytest.approx(((t - w0) - (w1 - t)) / (w1 - w0), abs=1e-12)


def test_a_pull_enabled_in_pincfg_alone_reaches_the_driver_at_its_time():
    """DS40001882 23.6.3.3 Pull configuration: an input with PINCFG.PULLEN is pulled up when OUT is one. PH as an
    input with OUT set reads low at the driver (its own pull-down) until a write of PINCFG alone enables the pull."""
    h = gpio_driver(ph_out=False)
    w0, w1 = window_after(h)
    h.advance_to(w0 + (w1 - w0) // 3)
    h.write(f"{G}.PINCFG[{PH}]", PINCFG_PULLEN)
    t = h.t_access
    assert h.pin_state(PH).level == 1 and not h.pin_state(PH).driven
    h.advance_to(w1 + 1)
    assert drive(h) == pytest.approx((-(t - w0) + (w1 - t)) / (w1 - w0), abs=1e-12)


def test_outset_of_a_pulled_eic_pin_flags_its_edge_and_a_repeated_one_does_not():
    """DS40001882 23.6.3.3 (Table 23-2): with PULLEN, OUT selects the pull's direction, also while PMUXEN gives
    the pin to the EIC (function A); 21.6.2.3: a rising edge on EXTINTn with SENSE RISE sets INTFLAG. OUTSET of
    the pin raises it; OUTSET again changes nothing and flags nothing; OUTTGL twice gives a falling and a rising
    edge."""
    pin, line = 3, 3  # PA03: EXTINT[3] on PMUX A, unconnected on a cell
    h = Harness()
    gclk_channel(h, GCLK_EIC)
    pmux(h, pin, "A", inen=True)
    h.write(f"{G}.PINCFG[{pin}]", PINCFG_PMUXEN | PINCFG_INEN | PINCFG_PULLEN)  # OUT 0: pulled down
    h.write("EIC.CONFIG[0]", 1 << (4 * line))  # SENSE3 = RISE
    h.write("EIC.CTRL", 1 << 1)
    h.advance(10e-6)
    h.write("EIC.INTFLAG", 0xFFFFFFFF)

    def flagged_after(reg: str) -> bool:
        h.write(f"{G}.{reg}", 1 << pin)
        h.advance(10e-6)
        f = bool(h.read("EIC.INTFLAG") >> line & 1)
        h.write("EIC.INTFLAG", 1 << line)
        return f

    assert [flagged_after(r) for r in ("OUTSET", "OUTSET", "OUTTGL", "OUTTGL")] == [True, False, False, True]
    assert h.pin_state(pin).level == 1 and h.pin_state(pin).function == 0


def pwm_run(pwm: str, noop: bool) -> tuple[list[tuple[float, float]], list[int]]:
    """TCC0 PWM on EN (PMUX F), the driver awake with PH high; a buffered duty and then a buffered period change,
    each taking over at an UPDATE inside a window. Every 20 us a PORT write: with `noop` one that changes nothing
    (OUTSET and DIRSET of set bits, PINCFG, PMUX and WRCONFIG of EN as they are), else one of the same size that
    changes a bit of an unconnected pin (the motors integrate up to it, as before every pin change): every CPU
    time the same in both runs. The alpha motor's (mean voltage, awake fraction) of five windows, and when the
    changes were written."""
    h = Harness(window_s=WINDOW_S, pwm=pwm)
    h.write(f"{G}.DIRSET", 1 << NSLEEP | 1 << PH)
    h.write(f"{G}.OUTSET", 1 << NSLEEP | 1 << PH)
    bus_clock(h, "TCC0")
    gclk_channel(h, GCLK_TCC0_TCC1)
    h.write("TCC0.WAVE", 0x2)  # NPWM
    h.write("TCC0.PER", 999)
    h.write("TCC0.CC[2]", 250)
    pmux(h, EN, "F")
    h.write("TCC0.CTRLA", 1 << 1)
    w = h.tu(WINDOW_S)
    t0 = (h.now() // w + 2) * w
    # EN through WRCONFIG as PINCFG and PMUX hold it (PA10: lower half, PMUXEN, PMUX F)
    wrconfig = 1 << 30 | 1 << 28 | 0x5 << 24 | 1 << 16 | 1 << EN
    same = [
        (f"{G}.OUTSET", 1 << NSLEEP | 1 << PH),
        (f"{G}.DIRSET", 1 << PH),
        (f"{G}.PINCFG[{EN}]", PINCFG_PMUXEN),
        (f"{G}.PMUX[{EN // 2}]", h.read(f"{G}.PMUX[{EN // 2}]")),
        (f"{G}.WRCONFIG", wrconfig),
    ]
    step = h.tu(20e-6)
    per_window = w // step
    actions = {17: ("TCC0.CCB[2]", 700), 2 * per_window + 11: ("TCC0.PERB", 899)}
    out, times = [], []
    for i in range(5 * per_window):
        h.advance_to(t0 + i * step)
        if i in actions:
            h.write(*actions[i])
            times.append(h.t_access)
        else:  # the reference changes a bit of an unconnected pin instead, with a store of the same size
            reg, value = same[i % len(same)]
            if not noop:
                reg, value = (f"{G}.OUTTGL", 1 << FREE) if h.address(reg)[1] == 4 else (f"{G}.PINCFG[{FREE}]", i & 1)
            h.write(reg, value)
        if (i + 1) % per_window == 0:
            h.advance_to(t0 + (i + 1) * step + 1)
            out.append(h.motor(0))
    assert h.read("TCC0.PER") == 899 and h.read("TCC0.CC[2]") == 700
    return out, times


@pytest.mark.parametrize("pwm", ["mean", "waveform"])
def test_a_port_write_that_changes_nothing_gives_the_drive_of_one_that_changes_an_unconnected_pin(pwm):
    """A PORT write that changes no register byte changes no pin: the plant's drive is the same to the last bit as
    with a write that changes only an unconnected pin at that time. The mean path sums the EN output's high time
    exactly while the period holds, in floating point across a period change (where a write must still cut the
    sum where it cut it before the PORT model skipped writes that change nothing)."""
    (ref, t_ref), (got, t_got) = pwm_run(pwm, noop=False), pwm_run(pwm, noop=True)
    assert t_got == t_ref  # the changes at the same times
    assert len(set(ref)) > 2  # the duty and the period changes moved the drive
    assert got == ref
