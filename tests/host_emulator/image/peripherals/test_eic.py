"""The EIC on the register-level harness: each sense mode on an external pin, the flag, its clearing and the
interrupt request, against the SAMD21 datasheet (Microchip DS40001882, chapter 21 "EIC - External Interrupt
Controller")."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness

from .bench import GCLK_EIC, gclk_channel, pmux

PIN = 3  # PA03: EXTINT[3] on PMUX A (7.1 Multiplexed Signals), unconnected on a cell
LINE = 3
SENSE = {"none": 0, "rise": 1, "fall": 2, "both": 3, "high": 4, "low": 5}  # 21.8.10 CONFIG.SENSEn
CTRL_ENABLE = 1 << 1
FILTEN = 1 << 3


def eic(sense: str, *, level0: int = 0, filten: bool = False) -> Harness:
    h = Harness()
    h.pin(PIN, level0)
    gclk_channel(h, GCLK_EIC)  # the EIC's APB clock is on after reset (PM.APBAMASK)
    pmux(h, PIN, "A", inen=True)
    h.write("EIC.CONFIG[0]", (SENSE[sense] | (FILTEN if filten else 0)) << (4 * LINE))
    h.write("EIC.INTENSET", 1 << LINE)
    h.write("EIC.CTRL", CTRL_ENABLE)
    h.advance(10e-6)
    h.write("EIC.INTFLAG", 0xFFFFFFFF)  # what enabling may have flagged (a level already present)
    h.write("NVIC.ICPR[0]", 1 << h.irq("EIC"))
    return h


def flagged(h: Harness) -> bool:
    return bool(h.read("EIC.INTFLAG") >> LINE & 1)


def edge(h: Harness, level: int) -> bool:
    """Drive the pin to `level`, let it be seen, and say whether the line's flag was set (then clear it)."""
    h.pin(PIN, level)
    h.advance(10e-6)
    f = flagged(h)
    h.write("EIC.INTFLAG", 1 << LINE)
    return f


@pytest.mark.parametrize(
    "sense, on_rise, on_fall",
    [("rise", True, False), ("fall", False, True), ("both", True, True), ("none", False, False)],
)
def test_edge_sense_modes_flag_the_edges_they_name(sense, on_rise, on_fall):
    """DS40001882 21.6.2.3 External Pin Processing (Table "Interrupt Sense Configuration"): RISE flags a rising
    edge, FALL a falling edge, BOTH either, NONE none; 21.8.9 INTFLAG.EXTINTn."""
    h = eic(sense)
    assert not flagged(h)
    assert edge(h, 1) is on_rise
    assert edge(h, 0) is on_fall
    assert edge(h, 1) is on_rise


@pytest.mark.parametrize("sense, active", [("high", 1), ("low", 0)])
def test_level_sense_flags_while_the_level_holds(sense, active):
    """DS40001882 21.6.2.3 External Pin Processing: with HIGH (LOW) sensing the flag is set while the pin is high
    (low); cleared while the level is still present, it is set again; once the level is gone it stays clear."""
    h = eic(sense, level0=1 - active)
    assert not flagged(h)
    h.pin(PIN, active)
    h.advance(10e-6)
    assert flagged(h)
    h.write("EIC.INTFLAG", 1 << LINE)
    assert flagged(h), "the level is still present: flagged again"
    h.pin(PIN, 1 - active)
    h.advance(10e-6)
    h.write("EIC.INTFLAG", 1 << LINE)
    assert not flagged(h)


def test_a_flag_with_its_interrupt_enabled_requests_the_eic_interrupt():
    """DS40001882 21.6.5 Interrupts: a set flag whose INTENSET bit is one requests the EIC interrupt (NVIC line 4,
    11.2.2 Interrupt Line Mapping) until cleared (writing one to INTFLAG, 21.8.9); INTENCLR disables it."""
    h = eic("rise")
    irq = h.irq("EIC")
    assert irq == 4 and irq not in h.pending()
    h.pin(PIN, 1)
    h.advance(10e-6)
    assert irq in h.pending() and h.nvic().level >> irq & 1
    h.write("EIC.INTFLAG", 1 << LINE)
    assert not h.nvic().level >> irq & 1
    h.write("NVIC.ICPR[0]", 1 << irq)
    h.write("EIC.INTENCLR", 1 << LINE)
    h.pin(PIN, 0)
    h.advance(10e-6)
    h.pin(PIN, 1)
    h.advance(10e-6)
    assert flagged(h) and irq not in h.pending()


def test_a_pin_not_muxed_to_the_eic_flags_nothing():
    """DS40001882 21.6.2.1 Initialization / 23.6.3.2 (PORT): the EIC sees a pin only when PINCFG.PMUXEN gives it
    to function A."""
    h = eic("both")
    h.write(f"PORT.Group[0].PINCFG[{PIN}]", 0x02)  # INEN only: a GPIO input
    h.pin(PIN, 1)
    h.advance(10e-6)
    assert not flagged(h)


@pytest.mark.xfail(strict=True, reason="model limit: the EIC's filter (CONFIG.FILTENn) is not modelled")
def test_the_filter_ignores_a_pulse_shorter_than_its_samples():
    """DS40001882 21.6.2.3 External Pin Processing, "Filtering": with FILTENn the input is sampled three times
    with GCLK_EIC and a majority decides: a pulse far shorter than one GCLK_EIC period is not seen."""
    h = eic("rise", filten=True)
    h.pin(PIN, 1)
    h.pin(PIN, 0)  # a glitch: high and back at the same instant
    h.advance(20e-6)
    assert not flagged(h)
