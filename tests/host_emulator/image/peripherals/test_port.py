"""PORT on the register-level harness: DIR and OUT with their SET/CLR/TGL aliases, IN, pulls, PINCFG and PMUX
(the door to the peripherals), WRCONFIG and the IOBUS door, against the SAMD21 datasheet (Microchip DS40001882,
chapter 23 "PORT - I/O Pin Controller")."""

from __future__ import annotations

from host_emulator.image.harness import Harness

G = "PORT.Group[0]"
A, B = 14, 15  # PA14, PA15: not wired on a cell
PINCFG_PMUXEN, PINCFG_INEN, PINCFG_PULLEN = 0x01, 0x02, 0x04  # 23.8.14 PINCFG
IOBUS = 0x6000_0000  # 9.2 Product Mapping: the single-cycle I/O port


def test_outset_outclr_outtgl_act_on_out_and_the_driven_pin():
    """DS40001882 23.6.2.1 Basic Operation and 23.8.5-23.8.8 OUT, OUTCLR, OUTSET, OUTTGL: writing one to a bit of
    OUTSET sets, of OUTCLR clears, of OUTTGL toggles that bit of OUT; zeros leave the others; reading the alias
    reads OUT. With DIR set the pin is driven to OUT."""
    h = Harness()
    h.write(f"{G}.DIRSET", 1 << A | 1 << B)
    assert h.read(f"{G}.DIR") & (1 << A | 1 << B) == 1 << A | 1 << B
    h.write(f"{G}.OUTSET", 1 << A)
    assert h.read(f"{G}.OUT") >> A & 1 and not h.read(f"{G}.OUT") >> B & 1
    assert h.read(f"{G}.OUTSET") == h.read(f"{G}.OUT") == h.read(f"{G}.OUTTGL")
    assert h.pin_state(A).level == 1 and h.pin_state(A).driven and h.pin_state(B).level == 0
    h.write(f"{G}.OUTTGL", 1 << A | 1 << B)
    assert h.pin_state(A).level == 0 and h.pin_state(B).level == 1
    h.write(f"{G}.OUTCLR", 1 << B)
    assert h.read(f"{G}.OUT") & (1 << A | 1 << B) == 0
    h.write(f"{G}.OUTSET", 0)
    assert h.read(f"{G}.OUT") & (1 << A | 1 << B) == 0


def test_dirset_dirclr_dirtgl_act_on_dir():
    """DS40001882 23.8.1-23.8.4 DIR, DIRCLR, DIRSET, DIRTGL; an input (DIR 0) is not driven by the MCU."""
    h = Harness()
    h.write(f"{G}.OUTSET", 1 << A)
    h.write(f"{G}.DIRTGL", 1 << A)
    assert h.read(f"{G}.DIR") >> A & 1 and h.pin_state(A).driven
    h.write(f"{G}.DIRCLR", 1 << A)
    assert not h.read(f"{G}.DIR") >> A & 1 and not h.pin_state(A).driven


def test_in_follows_the_pin_with_the_input_buffer_enabled():
    """DS40001882 23.6.2.2 Reading the pin state / 23.8.9 IN: IN holds the pin's level when PINCFG.INEN enables
    its input buffer (Table 23-2 Pin Configurations Summary), zero otherwise."""
    h = Harness()
    h.pin(A, 1)
    assert not h.read(f"{G}.IN") >> A & 1, "input buffer off"
    h.write(f"{G}.PINCFG[{A}]", PINCFG_INEN)
    assert h.read(f"{G}.IN") >> A & 1
    h.pin(A, 0)
    assert not h.read(f"{G}.IN") >> A & 1


def test_pulls_follow_out_when_nothing_drives_the_pin():
    """DS40001882 23.6.3.3 Pull configuration (Table 23-2): an input with PULLEN is pulled up when OUT is one and
    down when OUT is zero; an external driver wins over the pull."""
    h = Harness()
    h.write(f"{G}.PINCFG[{A}]", PINCFG_INEN | PINCFG_PULLEN)
    h.write(f"{G}.OUTSET", 1 << A)
    assert h.read(f"{G}.IN") >> A & 1 and not h.pin_state(A).driven
    h.write(f"{G}.OUTCLR", 1 << A)
    assert not h.read(f"{G}.IN") >> A & 1
    h.pin(A, 1)
    assert h.read(f"{G}.IN") >> A & 1


def test_pmuxen_gives_the_pin_to_the_function_pmux_names():
    """DS40001882 23.6.3.4 Peripheral Multiplexing, 23.8.13 PMUX (PMUXE for the even pin in bits 3:0, PMUXO for
    the odd one in bits 7:4) and 23.8.14 PINCFG.PMUXEN: with PMUXEN the peripheral function selected by PMUX owns
    the pin and the GPIO output no longer drives it."""
    h = Harness()
    h.write(f"{G}.DIRSET", 1 << A)
    h.write(f"{G}.OUTSET", 1 << A)
    h.write(f"{G}.PMUX[{A // 2}]", 0x5 << 4 | 0x2)  # PA14 C, PA15 F
    assert h.pin_state(A).function == -1 and h.pin_state(A).driven
    h.write(f"{G}.PINCFG[{A}]", PINCFG_PMUXEN)
    h.write(f"{G}.PINCFG[{B}]", PINCFG_PMUXEN)
    assert h.pin_state(A).function == 2 and h.pin_state(B).function == 5
    assert not h.pin_state(A).driven
    h.write(f"{G}.PINCFG[{A}]", 0)
    assert h.pin_state(A).function == -1 and h.pin_state(A).driven


def test_wrconfig_writes_pincfg_and_pmux_of_many_pins_at_once():
    """DS40001882 23.8.12 WRCONFIG: PINMASK selects pins of the lower (HWSEL 0) or upper half; WRPINCFG writes
    their PINCFG (PMUXEN, INEN, PULLEN), WRPMUX their PMUX; it reads as zero."""
    h = Harness()
    wr = 1 << 31 | 1 << 30 | 1 << 28 | 0x3 << 24 | 1 << 17 | 1 << 16  # HWSEL, WRPINCFG, WRPMUX, PMUX D, INEN, PMUXEN
    h.write(f"{G}.WRCONFIG", wr | 1 << (20 - 16) | 1 << (21 - 16))  # PA20, PA21
    for pin in (20, 21):
        assert h.read(f"{G}.PINCFG[{pin}]") == PINCFG_PMUXEN | PINCFG_INEN
        assert h.pin_state(pin).function == 3
    assert h.read(f"{G}.PMUX[10]") == 0x33
    assert h.read(f"{G}.PINCFG[19]") == 0 and h.pin_state(22).function == -1


def test_the_iobus_is_another_door_to_the_same_registers():
    """DS40001882 23.5.9 / 23.6.3.7 Single-cycle access (IOBUS): the PORT registers are also reached at
    0x60000000 with the same offsets."""
    h = Harness()
    out = h.table.reg("PORT", "Group[0].OUTSET").offset
    h.write(IOBUS + h.table.reg("PORT", "Group[0].DIRSET").offset, 1 << A)
    h.write(IOBUS + out, 1 << A)
    assert h.read(f"{G}.OUT") >> A & 1 and h.pin_state(A).level == 1
    assert h.read(IOBUS + h.table.reg("PORT", "Group[0].OUT").offset) == h.read(f"{G}.OUT")
