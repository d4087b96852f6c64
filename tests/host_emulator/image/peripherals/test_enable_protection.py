"""Enable protection on the register-level harness: the fields the SAMD21 datasheet (Microchip DS40001882) marks
"Enable-Protected" keep their value when written while their peripheral is enabled, take it while it is
disabled, and the ignored write is noted (csrc/sam_protect.c holds the table, one line per register with its
section): WDT CONFIG (18.8.2), TC CTRLA (30.8.1), SERCOM I2C CTRLA and the master's BAUD (chapter 28)."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness
from tests.host_emulator.image.conftest import configured

from .bench import (
    GCLK_SERCOM2_CORE,
    GCLK_TCC0_TCC1,
    GCLK_TCC2_TC3,
    GCLK_WDT,
    TU_PER_US_AT_1MHZ,
    bus_clock,
    gclk_channel,
    pmux,
    tcc_count,
)
from .test_wdt import CTRL_ENABLE, HZ, TIMEOUT_S

ENABLE = 1 << 1
MODE_MASTER = 0x5 << 2


def _noted(h: Harness, reg: str) -> bool:
    return any("enable-protected" in n and f" {reg} " in n for n in h.notes())


def _watchdog() -> Harness:
    h = Harness()
    h.write("GCLK.GENDIV", 2)
    h.write("GCLK.GENCTRL", 2 | 0x03 << 8 | 1 << 16)  # generator 2: OSCULP32K undivided
    gclk_channel(h, GCLK_WDT, gen=2)
    return h


def test_the_watchdog_enabled_before_its_configuration_keeps_its_old_period():
    """18.8.2 CONFIG (Enable-Protected): a CONFIG written after CTRL.ENABLE is ignored, so the period in force is
    the one before (here the reset value PER = 0xB, 16384 cycles, the fuse's on a board): no reset within the
    64-cycle period the image meant, and the write is noted."""
    h = _watchdog()
    h.write("WDT.CTRL", CTRL_ENABLE)
    h.advance(10 / HZ)
    old = h.read("WDT.CONFIG")
    h.write("WDT.CONFIG", 0x3)  # 64 cycles
    assert h.read("WDT.CONFIG") == old != 0x3
    h.advance(4 * TIMEOUT_S)
    assert h.info().resets == 1, "the ignored period took effect"
    assert _noted(h, "WDT.CONFIG")


def test_the_watchdog_configured_while_disabled_takes_its_period():
    """18.6.2.1 Initialization: CONFIG written while the WDT is disabled is taken; no note."""
    h = _watchdog()
    h.write("WDT.CONFIG", 0x3)
    assert h.read("WDT.CONFIG") & 0xF == 0x3
    h.write("WDT.CTRL", CTRL_ENABLE)
    h.advance(TIMEOUT_S + 10 / HZ)
    assert h.info().resets == 2
    assert not _noted(h, "WDT.CONFIG")


def test_tc_ctrla_fields_are_kept_while_enabled_and_enable_still_clears():
    """30.8.1 CTRLA (Enable-Protected: PRESCSYNC, RUNSTDBY, PRESCALER, WAVEGEN, MODE; not ENABLE, SWRST): a new
    PRESCALER written with ENABLE still set is ignored; writing ENABLE = 0 disables; then the PRESCALER is taken."""
    h = Harness()
    bus_clock(h, "TC3")
    gclk_channel(h, GCLK_TCC2_TC3)
    h.write("TC3.COUNT16.CTRLA", ENABLE)
    h.advance(20e-6)
    h.write("TC3.COUNT16.CTRLA", ENABLE | 0x5 << 8)  # PRESCALER DIV64
    assert h.read("TC3.COUNT16.CTRLA") == ENABLE
    assert _noted(h, "TC3.COUNT16.CTRLA")
    h.write("TC3.COUNT16.CTRLA", 0)
    h.advance(20e-6)
    h.write("TC3.COUNT16.CTRLA", 0x5 << 8)
    assert h.read("TC3.COUNT16.CTRLA") == 0x5 << 8


@pytest.mark.parametrize("reg, value", [("SERCOM2.I2CM.BAUD", 0x20), ("SERCOM2.I2CM.CTRLA", 3 << 20)])
def test_the_i2c_master_keeps_its_baud_and_ctrla_fields_while_enabled(reg, value):
    """Chapter 28, I2C master BAUD and CTRLA (Enable-Protected but SWRST and ENABLE): written while enabled they
    keep their value (SDAHOLD here for CTRLA)."""
    h = Harness(board="primary")
    bus_clock(h, "SERCOM2")
    gclk_channel(h, GCLK_SERCOM2_CORE)
    pmux(h, 8, "D")
    pmux(h, 9, "D")
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER)
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER | ENABLE)
    h.advance(20e-6)
    before = h.read(reg)
    h.write(reg, before | value)
    assert h.read(reg) == before
    assert _noted(h, reg)


TCC_PRESCALER_DIV64 = 0x5 << 8


def _tcc0_enabled() -> Harness:
    h = Harness()
    bus_clock(h, "TCC0")
    gclk_channel(h, GCLK_TCC0_TCC1)
    h.write("TCC0.WAVE", 0x2)  # NPWM
    h.write("TCC0.PER", 999)
    h.write("TCC0.CTRLA", ENABLE)
    h.advance(20e-6)
    return h


def test_tcc_ctrla_prescaler_written_while_counting_is_kept_and_the_counter_runs_on_at_its_rate():
    """31.8.1 CTRLA (Enable-Protected: RESOLUTION, PRESCALER, RUNSTDBY, PRESCSYNC, ALOCK, CPTENn; not ENABLE,
    SWRST): PRESCALER = DIV64 written with ENABLE still set is ignored, the counter still counts at GCLK rate
    (1 MHz: one count per microsecond between two READSYNCs, not one per 64), and the write is noted; disabled, the
    same write is taken."""
    h = _tcc0_enabled()
    h.write("TCC0.CTRLA", ENABLE | TCC_PRESCALER_DIV64)
    assert h.read("TCC0.CTRLA") & 0x0F007F60 == 0
    assert _noted(h, "TCC0.CTRLA")
    c0, t0 = tcc_count(h)
    h.advance(100e-6)
    c1, t1 = tcc_count(h)
    assert 100 <= (t1 - t0) // TU_PER_US_AT_1MHZ <= 150  # the counts are those of the READSYNCs' times
    assert abs((c1 - c0) % 1000 - (t1 - t0) // TU_PER_US_AT_1MHZ) <= 1  # one count per GCLK cycle
    h.write("TCC0.CTRLA", 0)
    h.advance(20e-6)
    h.write("TCC0.CTRLA", TCC_PRESCALER_DIV64)
    assert h.read("TCC0.CTRLA") == TCC_PRESCALER_DIV64


def test_tcc_ctrla_capture_enable_written_while_counting_is_ignored():
    """31.8.1 CTRLA.CPTENn (Enable-Protected): a capture channel enabled while the TCC counts stays off (no
    capture starts: the model, which has no capture channels, runs on) and the write is noted."""
    h = _tcc0_enabled()
    h.write("TCC0.CTRLA", ENABLE | 1 << 24)
    assert h.read("TCC0.CTRLA") == ENABLE
    assert _noted(h, "TCC0.CTRLA")
    h.advance(50e-6)


@pytest.mark.parametrize("reg", ["TCC0.DRVCTRL", "TCC0.WEXCTRL", "TCC0.EVCTRL", "TCC0.FCTRLA", "TCC0.FCTRLB"])
def test_tcc_registers_enable_protected_as_a_whole_keep_their_value_while_counting(reg):
    """31.8 Register Description: FCTRLA, FCTRLB, WEXCTRL, DRVCTRL and EVCTRL are Enable-Protected as a whole; a
    write while CTRLA.ENABLE reads 1 leaves them at their value (here the reset value 0) and is noted, once per
    register."""
    h = _tcc0_enabled()
    h.write(reg, 0x10)
    h.write(reg, 0x20)
    assert h.read(reg) == 0
    assert sum(f" {reg} " in n and "enable-protected" in n for n in h.notes()) == 1
    h.advance(50e-6)


def test_tcc_wave_is_not_enable_protected_on_the_samd21():
    """31.8.14 WAVE: Write-Synchronized, not Enable-Protected on the SAMD21 (its WAVEB buffer exists for the
    running TCC); a write while counting is no protection note."""
    h = _tcc0_enabled()
    h.write("TCC0.WAVE", 0x2)
    assert h.read("TCC0.WAVE") == 0x2
    assert not _noted(h, "TCC0.WAVE")


def test_the_shipped_images_make_no_write_to_an_enable_protected_register_while_enabled(images):
    """The cell and primary images, brought up and running a push: none of their writes is one the table would
    ignore (so protection changes none of their results), and no note says so."""
    w, lap = configured(images, 2)
    notes = list(w.take_notes())
    lap.pump(0.05)
    notes += w.take_notes()
    assert not [n for n in notes if "enable-protected" in n]
