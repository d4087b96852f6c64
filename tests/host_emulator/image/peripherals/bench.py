"""Helpers of the per-peripheral tests: bus clocks and generic clock channels set as the firmware sets them."""

from __future__ import annotations

from host_emulator.image.harness import Harness

# GCLK.CLKCTRL.ID of the generic clock channels used here (DS40001882 15.8.3 CLKCTRL, ID table)
GCLK_EIC = 0x05
GCLK_WDT = 0x03
GCLK_SERCOM2_CORE = 0x16
GCLK_SERCOMX_SLOW = 0x13
GCLK_TCC0_TCC1 = 0x1A
GCLK_TCC2_TC3 = 0x1B
CLKCTRL_CLKEN = 1 << 14
CLKCTRL_GEN_POS = 8
TU_PER_US_AT_1MHZ = 1536  # tu of one cycle of the 1 MHz reset clock (GCLK0 = OSC8M / 8)
CMD_READSYNC = 0x4 << 5  # TCC CTRLBSET.CMD = READSYNC (DS40001882 31.8.3)
SYNCBUSY_CTRLB = 1 << 2  # TCC SYNCBUSY.CTRLB


def bus_clock(h: Harness, periph: str, *, board: int = 0) -> None:
    """Set the peripheral's bit in the PM APBxMASK that has a field of its name (DS40001882 16.6.2.6)."""
    for reg in ("PM.APBAMASK", "PM.APBBMASK", "PM.APBCMASK"):
        periph_reg = h.table.reg("PM", reg.split(".", 1)[1])
        f = periph_reg.field(periph)
        if f is not None:
            h.write(reg, h.read(reg, board=board) | f.mask, board=board)
            return
    raise KeyError(f"{periph}: no APB mask bit")


def systick_free_running(h: Harness, load: int = 0xFFFFFF) -> None:
    """SysTick counting down from `load` on the processor clock, VAL cleared, no interrupt (CTRL = ENABLE |
    CLKSOURCE): a clock the program reads."""
    h.write("SysTick.LOAD", load)
    h.write("SysTick.VAL", 0)
    h.write("SysTick.CTRL", 0x5)


def gclk_channel(h: Harness, channel: int, gen: int = 0, *, board: int = 0) -> None:
    """Feed a generic clock channel from a generator (GCLK0 after reset: OSC8M / 8 = 1 MHz)."""
    h.write("GCLK.CLKCTRL", channel | gen << CLKCTRL_GEN_POS | CLKCTRL_CLKEN, board=board)


def tcc_count(h: Harness, tcc: str = "TCC0", *, sync_tu: int = 3 * TU_PER_US_AT_1MHZ) -> tuple[int, int]:
    """COUNT read as firmware must read it: after the READSYNC command (31.8.3 CTRLBSET.CMD) has brought it over.
    Returns the count and the time (tu) it is the count of: when the command's synchronisation completed, 3 GCLK
    cycles after its write (of the 1 MHz reset clock unless sync_tu says otherwise)."""
    h.write(f"{tcc}.CTRLBSET", CMD_READSYNC)
    t = h.t_access + sync_tu
    while h.read(f"{tcc}.SYNCBUSY") & SYNCBUSY_CTRLB:
        pass
    return h.read(f"{tcc}.COUNT"), t


def pmux(h: Harness, pin: int, letter: str, *, inen: bool = False, board: int = 0) -> None:
    """Give a PA pin to a peripheral function (PMUX letter A..H) through PINCFG and PMUX."""
    g, b = pin // 32, pin % 32
    half = f"PORT.Group[{g}].PMUX[{b // 2}]"
    func = "ABCDEFGH".index(letter)
    old = h.read(half, board=board)
    new = (old & 0x0F) | func << 4 if b & 1 else (old & 0xF0) | func
    h.write(half, new, board=board)
    h.write(f"PORT.Group[{g}].PINCFG[{b}]", 0x01 | (0x02 if inen else 0), board=board)


def sercom2_i2c_pins(h: Harness, boards: tuple[int, ...]) -> None:
    """SERCOM2's bus clock and core clock on each board, PA08/PA09 on its PAD[0] SDA and PAD[1] SCL (function D,
    DS40001882 7.1 Multiplexed Signals): the boards share the I2C bus."""
    for b in boards:
        bus_clock(h, "SERCOM2", board=b)
        gclk_channel(h, GCLK_SERCOM2_CORE, board=b)
        pmux(h, 8, "D", board=b)
        pmux(h, 9, "D", board=b)
