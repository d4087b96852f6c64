"""The register layer on the register-level harness: reserved bytes inside a wider access read as zero and ignore
writes (DS40001882: reserved bits read as zero, writing them has no effect), while an access that starts on no
register stays an error; the pattern of bossac's `readWord(0x41004018)` (NVMCTRL.STATUS, 16 bits, as a word)."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness, HarnessError

NVM = 0x4100_4000
INTFLAG, STATUS = NVM + 0x14, NVM + 0x18  # 8-bit at 0x14 (0x15-0x17 reserved), 16-bit at 0x18 (0x1A-0x1B reserved)
PROGE = 1 << 2


def test_a_word_read_of_a_narrower_register_reads_its_reserved_bytes_as_zero():
    h = Harness()
    assert h.read(STATUS, 4) == 0
    h.write("NVMCTRL.CTRLA", 0x0002)  # a command without the key: STATUS.PROGE
    assert h.read(STATUS, 4) == PROGE
    assert h.read(INTFLAG, 4) == 0b11  # READY | ERROR, bytes 0x15-0x17 zero


def test_a_word_write_reaches_the_register_and_ignores_its_reserved_bytes():
    h = Harness()
    h.write("NVMCTRL.CTRLA", 0x0002)
    h.write(STATUS, 0xFFFF_0000 | PROGE, 4)  # bossac clears the flags with a word write
    assert h.read("NVMCTRL.STATUS") == 0


def test_an_access_starting_on_a_reserved_byte_is_an_error():
    h = Harness()
    with pytest.raises(HarnessError, match=r"NVMCTRL \+ 0x1a: no register at that offset"):
        h.read(STATUS + 2, 2)
