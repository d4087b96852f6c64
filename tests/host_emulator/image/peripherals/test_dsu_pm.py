"""What the UF2 bootloader and bossac read of the chip, on the register-level harness: DSU.DID (bossac's
`readWord(0x41002018)`: a SAMD21G18A), and PM.RCAUSE with SRAM kept across a reset that is not a power-on (the
bootloader's double-tap word at 0x20007FFC), against DS40001882 chapters 13 "DSU" (DID) and 16 "PM" (RCAUSE)."""

from __future__ import annotations

from host_emulator.image.harness import Harness

DID = 0x4100_2018
SAMD21G18A_DID = 0x1001_0305  # PROCESSOR 1 (M0+), FAMILY 0, SERIES 1, DIE 0, REVISION 3, DEVSEL 0x05 (G18A)
RCAUSE_POR, RCAUSE_SYST = 1 << 0, 1 << 6
DOUBLE_TAP = 0x2000_7FFC
MAGIC = 0xF016_69EF


def test_dsu_did_is_a_samd21g18a():
    assert Harness().read(DID, 4) == SAMD21G18A_DID


def test_sram_is_kept_across_a_system_reset_and_rcause_says_syst():
    h = Harness()
    assert h.read("PM.RCAUSE") == RCAUSE_POR
    h.write(DOUBLE_TAP, MAGIC, 4)
    h.write("SCB.AIRCR", 0x05FA_0004)  # SYSRESETREQ
    info = h.info()
    assert info.resets == 2 and info.reset_cause == RCAUSE_SYST
    assert h.read("PM.RCAUSE") == RCAUSE_SYST
    assert h.read(DOUBLE_TAP, 4) == MAGIC
