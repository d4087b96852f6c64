"""PAC write protection on the register-level harness, against the SAMD21 datasheet (DS40001882) 11.6 "PAC -
Peripheral Access Controller" and the vendor's headers (ID_<name> of samd21g18a.h: bit ID % 32 of PAC ID // 32;
PACn_WPROT_DEFAULT_VAL of instance/pacN.h): WPSET sets a peripheral's protection and WPCLR clears it, both read
the mask; a store to a protected peripheral is refused with a bus error (HardFault, the store's address stacked),
also right after the WPSET in the same block; reads go on; other peripherals are not affected; a double protection
or unprotection is an error too; a reset restores the reset masks."""

from __future__ import annotations

import re

import pytest

from host_emulator.image import regsnapshot
from host_emulator.image.harness import Asm, Harness, stub
from tests.host_emulator.image.vendor import include_dirs

from .bench import bus_clock

TABLE = regsnapshot.load_or_snapshot()


def addr(reg: str) -> int:
    periph, name = reg.split(".", 1)
    return TABLE.periph(periph).base + TABLE.reg(periph, name).offset


def pac_bit(periph: str) -> tuple[str, int]:
    """(the PAC's WPSET/WPCLR prefix, the bit) of a peripheral, from the table (ID_<name>)."""
    pid = TABLE.periph(periph).pac
    assert pid is not None
    return f"PAC{pid // 32}", 1 << (pid % 32)


OUTSET, OUT = "PORT.Group[0].OUTSET", "PORT.Group[0].OUT"
PAC1, PORT_BIT = pac_bit("PORT")


def _sites(a: Asm) -> dict[int, str]:
    """`store`: str r1, [r0]. `set_then_store`: WPSET of PORT, then a store to PORT in the same block (no branch
    between). `clear_then_store`: WPCLR of PORT, then the store, same block, ending at `clear_done`. The HardFault
    handler puts the stacked PC in R1 and stops at `hf_done`."""
    a.label("store")
    a.mem("str", 1, 0)
    a.b()
    for name, reg in (("set_then_store", f"{PAC1}.WPSET"), ("clear_then_store", f"{PAC1}.WPCLR")):
        a.label(name)
        a.ldr_const(2, addr(reg))
        a.ldr_const(3, PORT_BIT)
        a.mem("str", 3, 2)
        a.ldr_const(2, addr(OUTSET))
        a.movs(3, 1)
        a.label(f"{name}_store")
        a.mem("str", 3, 2)
        a.label(f"{name}_done")
        a.b()
        a.pool()
    a.label("hf")
    a.mov_from_sp(0)
    a.mem("ldr", 1, 0, 24)
    a.label("hf_done")
    a.b()
    return {3: "hf"}


def _board() -> Harness:
    return Harness(program=stub(_sites))


def _faults_at(h: Harness, label: str, done: str, *, r0: int = 0, r1: int = 0) -> None:
    """Running from `label` enters HardFault with `label`'s store stacked as the return address (or the label
    `done` names)."""
    stacked = h.call(label, "hf_done", r0=r0, r1=r1)
    assert h.error() is None, h.error()
    assert stacked == h.program.labels[done]
    assert h.nvic().sys_active == 1 << 3


def _header_default(k: int) -> int:
    atmel, _ = include_dirs()
    text = (atmel / "instance" / f"pac{k}.h").read_text()
    m = re.search(rf"#define\s+PAC{k}_WPROT_DEFAULT_VAL\s+(0x[0-9A-Fa-f]+)", text)
    assert m, f"PAC{k}_WPROT_DEFAULT_VAL not in instance/pac{k}.h"
    return int(m.group(1), 16)


def test_the_masks_read_the_headers_reset_values_through_both_registers():
    """11.6.2: WPCLR and WPSET read the same mask; at reset it is PACn_WPROT_DEFAULT_VAL (PAC1's protects the DSU,
    bit 1 = ID_DSU - 32)."""
    h = _board()
    bus_clock(h, "PAC2")  # PAC0 and PAC1 are clocked from reset, PAC2 is not (PM APBCMASK)
    for k in range(3):
        want = _header_default(k) & ~1
        assert h.read(f"PAC{k}.WPSET") == h.read(f"PAC{k}.WPCLR") == want
    assert h.read("PAC1.WPSET") >> (TABLE.periph("DSU").pac % 32) & 1


def test_wpset_protects_and_wpclr_unprotects_and_both_read_the_mask():
    h = _board()
    base = h.read(f"{PAC1}.WPSET")
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    assert h.read(f"{PAC1}.WPSET") == h.read(f"{PAC1}.WPCLR") == base | PORT_BIT
    h.write(f"{PAC1}.WPCLR", PORT_BIT)
    assert h.read(f"{PAC1}.WPSET") == h.read(f"{PAC1}.WPCLR") == base
    h.write(f"{PAC1}.WPSET", PORT_BIT, size=1)  # 11.6.2: the 8-bit quarters can be written alone
    assert h.read(f"{PAC1}.WPSET") == base | PORT_BIT
    h.write(f"{PAC1}.WPSET", 1)  # bit 0 is the PAC itself: reserved, never protected
    assert h.read(f"{PAC1}.WPSET") == base | PORT_BIT and h.info().hardfaults == 0


def test_a_store_to_a_protected_peripheral_takes_a_bus_error_at_the_store_and_is_not_done():
    """11.6.1: "data will not be written, and the peripheral will return an access error (CPU exception)": the
    store enters HardFault with its own address stacked; OUT keeps its value; the board's log says why, once."""
    h = _board()
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    _faults_at(h, "store", "store", r0=addr(OUTSET), r1=1)
    assert h.info().hardfaults == 1
    assert h.read(OUT) == 0
    notes = [n for n in h.notes() if "HardFault" in n]
    assert len(notes) == 1 and "write to PORT + 0x18, write-protected by PAC1" in notes[0], notes


def test_reads_of_a_protected_peripheral_go_on():
    h = _board()
    h.write("PORT.Group[0].DIRSET", 1 << 5)
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    assert h.read("PORT.Group[0].DIR") == 1 << 5
    assert h.info().hardfaults == 0 and h.error() is None


def test_wpclr_gives_the_writes_back():
    h = _board()
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    h.write(f"{PAC1}.WPCLR", PORT_BIT)
    h.write(OUTSET, 1 << 7)
    assert h.read(OUT) == 1 << 7 and h.info().hardfaults == 0


def test_the_store_right_after_wpset_in_the_same_block_is_refused():
    """The new protection holds from the next instruction: the translation the CPU made of PORT's page for the
    store before (writes allowed) does not let the store through."""
    h = _board()
    h.write("PORT.Group[0].DIRSET", 1 << 5)
    _faults_at(h, "set_then_store", "set_then_store_store")
    assert h.read(f"{PAC1}.WPSET") & PORT_BIT
    assert h.read(OUT) == 0


def test_the_store_right_after_wpclr_in_the_same_block_is_done():
    h = _board()
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    h.call("clear_then_store", "clear_then_store_done")
    assert h.read(OUT) == 1 and h.info().hardfaults == 0 and h.error() is None


def test_other_peripherals_are_not_affected():
    """PM (PAC0) and PORT (PAC1) protected: their neighbours on the same bridges (SYSCTRL next to PM, NVMCTRL and
    DMAC on either side of PORT), the PACs themselves and SRAM take their writes."""
    h = _board()
    pac0, pm_bit = pac_bit("PM")
    h.write(f"{pac0}.WPSET", pm_bit)
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    for reg, value in (("SYSCTRL.DFLLMUL", 0x0400_BB80), ("NVMCTRL.CTRLB", 1 << 1), ("DMAC.QOSCTRL", 0x15)):
        h.write(reg, value)
        assert h.read(reg) == value, reg
    h.write(0x2000_0100, 0xA5A5_5A5A, 4)
    assert h.read(0x2000_0100, 4) == 0xA5A5_5A5A
    assert h.info().hardfaults == 0 and h.error() is None
    _faults_at(h, "store", "store", r0=addr("PM.CPUSEL"), r1=0)


@pytest.mark.parametrize("reg", ["WPSET", "WPCLR"])
def test_a_double_protection_or_unprotection_is_a_bus_error(reg):
    """11.6.1: "a CPU exception generated on double write-protection or double unprotection of a peripheral": a one
    written to WPSET[n] already set, or to WPCLR[n] already clear, takes a bus error at that store; the mask
    stays."""
    h = _board()
    if reg == "WPSET":
        h.write(f"{PAC1}.WPSET", PORT_BIT)
    before = h.read(f"{PAC1}.WPSET")
    _faults_at(h, "store", "store", r0=addr(f"{PAC1}.{reg}"), r1=PORT_BIT)
    assert h.read(f"{PAC1}.WPSET") == before
    notes = [n for n in h.notes() if "HardFault" in n]
    assert len(notes) == 1 and f"{PAC1}.{reg} of bit 3 (PORT)" in notes[0], notes


def test_the_dsu_is_protected_from_reset():
    """PAC1_WPROT_DEFAULT_VAL sets the DSU's bit: a store to the DSU after reset takes a bus error."""
    h = _board()
    _faults_at(h, "store", "store", r0=addr("DSU.CTRL"), r1=0)


def test_a_reset_restores_the_reset_masks():
    h = _board()
    base = h.read(f"{PAC1}.WPSET")
    h.write(f"{PAC1}.WPSET", PORT_BIT)
    h.write("SCB.AIRCR", 0x05FA_0004)  # SYSRESETREQ
    assert h.info().resets == 2
    assert h.read(f"{PAC1}.WPSET") == base
    h.write(OUTSET, 1)
    assert h.read(OUT) == 1 and h.info().hardfaults == 0
