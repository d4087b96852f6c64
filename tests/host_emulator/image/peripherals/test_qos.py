"""Bus quality-of-service registers the UF2 bootloader writes at start-up, on the register-level harness: SBMATRIX
(HMATRIXB: PRAS/PRBS, SFR) and DMAC.QOSCTRL are storage (DS40001882 chapters 11 "HMATRIXB" and 20 "DMAC"); the DMA
controller itself is not modelled, and any other DMAC register is an error naming it."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness, HarnessError

SBMATRIX = 0x4100_7000


def test_sbmatrix_registers_are_storage():
    h = Harness()
    h.write(SBMATRIX + 0x120, 0x0000_0002, 4)  # SFR[4]: what the bootloader writes (the SRAM slave's QoS)
    assert h.read(SBMATRIX + 0x120, 4) == 2
    h.write("SBMATRIX.Prs[2].PRAS", 0x3333_3333)
    assert h.read("SBMATRIX.Prs[2].PRAS") == 0x3333_3333


def test_dmac_qosctrl_is_storage_with_its_reset_value():
    h = Harness()
    assert h.read("DMAC.QOSCTRL") == 0x15  # DQOS = FQOS = WRBQOS = 1 (MEDIUM)
    h.write("DMAC.QOSCTRL", 0x2A)
    assert h.read("DMAC.QOSCTRL") == 0x2A


def test_any_other_dmac_register_is_an_error_naming_it():
    h = Harness()
    with pytest.raises(HarnessError, match="DMAC.CTRL: the DMA controller is not modelled"):
        h.write("DMAC.CTRL", 1 << 1)  # DMAENABLE
