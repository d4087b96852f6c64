"""The WDT on the register-level harness: enable, the timeout and the system reset it causes (reset cause WDT),
clearing with the key, the wrong key, against the SAMD21 datasheet (Microchip DS40001882, chapter 18 "WDT -
Watchdog Timer", and 16 "PM - Power Manager" for the reset cause)."""

from __future__ import annotations

from host_emulator.image.harness import Harness

from .bench import GCLK_WDT, gclk_channel

CTRL_ENABLE = 1 << 1
KEY = 0xA5
RCAUSE_POR, RCAUSE_SYST, RCAUSE_WDT = 1 << 0, 1 << 6, 1 << 5  # 16.8.14 RCAUSE
PER = 0x3  # 18.8.2 CONFIG.PER: 64 cycles of GCLK_WDT
HZ = 32768  # GCLK_WDT from generator 2 on OSCULP32K, undivided
TIMEOUT_S = 64 / HZ


def watchdog() -> Harness:
    h = Harness()
    h.write("GCLK.GENDIV", 2)  # generator 2 undivided (DIV = 0)
    h.write("GCLK.GENCTRL", 2 | 0x03 << 8 | 1 << 16)  # generator 2: OSCULP32K, GENEN
    gclk_channel(h, GCLK_WDT, gen=2)
    h.write("WDT.CONFIG", PER)
    assert h.info().resets == 1 and h.read("PM.RCAUSE") == RCAUSE_POR
    h.write("WDT.CTRL", CTRL_ENABLE)
    return h


def test_the_timeout_resets_the_system_with_cause_wdt():
    """DS40001882 18.6.2.4 Normal Mode: enabled, the WDT issues a system reset when it is not cleared within the
    time-out period, CONFIG.PER cycles of GCLK_WDT (64 at PER = 0x3, 18.8.2); 16.8.14 RCAUSE.WDT records it. The
    enable synchronises first (18.6.5 Synchronization: a few GCLK_WDT cycles)."""
    h = watchdog()
    t_en = h.t_access
    sync = 6 / HZ
    h.advance_to(t_en + h.tu(TIMEOUT_S * 0.97))
    assert h.info().resets == 1, "no reset before the time-out"
    h.advance_to(t_en + h.tu(TIMEOUT_S + sync))
    info = h.info()
    assert info.resets == 2 and info.reset_cause == RCAUSE_WDT
    assert h.read("PM.RCAUSE") == RCAUSE_WDT
    assert h.read("WDT.CTRL") & CTRL_ENABLE == 0, "the reset disabled it (18.8.1 CTRL reset value)"
    h.advance(10 * TIMEOUT_S)
    assert h.info().resets == 2


def test_clearing_with_the_key_restarts_the_period():
    """DS40001882 18.6.2.4 Normal Mode and 18.8.8 CLEAR: writing the key 0xA5 to CLEAR clears the WDT (its period
    restarts); cleared more often than the time-out, it never resets the system."""
    h = watchdog()
    for _ in range(12):
        h.advance(TIMEOUT_S * 0.6)
        h.write("WDT.CLEAR", KEY)
    assert h.info().resets == 1
    t_last = h.t_access
    h.advance_to(t_last + h.tu(TIMEOUT_S * 0.9))
    assert h.info().resets == 1
    h.advance_to(t_last + h.tu(TIMEOUT_S * 1.3))
    assert h.info().resets == 2 and h.info().reset_cause == RCAUSE_WDT


def test_a_wrong_key_resets_the_system_at_once():
    """DS40001882 18.8.8 CLEAR: "Writing any other value than 0xA5 to CLEAR will issue an immediate system
    reset"; the cause is the WDT (16.8.14 RCAUSE)."""
    h = watchdog()
    h.advance(TIMEOUT_S * 0.3)
    h.write("WDT.CLEAR", 0x5A)
    info = h.info()
    assert info.resets == 2 and info.reset_cause == RCAUSE_WDT


def test_a_disabled_watchdog_never_resets():
    """DS40001882 18.6.2.1 Initialization: the WDT is disabled after a power-on reset (CTRL.ENABLE = 0)."""
    h = Harness()
    h.advance(0.05)
    assert h.info().resets == 1 and h.read("PM.RCAUSE") == RCAUSE_POR


def test_a_software_reset_request_is_cause_syst():
    """DS40001882 16.8.14 RCAUSE.SYST: a reset requested by the CPU (AIRCR.SYSRESETREQ, ARMv6-M B3.2.6)."""
    h = Harness()
    h.write("SCB.AIRCR", 0x05FA0004)
    assert h.info().resets == 2 and h.read("PM.RCAUSE") == RCAUSE_SYST
