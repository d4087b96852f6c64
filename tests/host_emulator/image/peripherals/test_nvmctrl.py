"""NVMCTRL programming the flash on the register-level harness: page buffer, erase row, write page, automatic page
write, the key, BOOTPROT and the lock bits from the user row, the error flags, the CPU stall, and code rewritten in
flash running as rewritten, against the SAMD21 datasheet (Microchip DS40001882, chapter 22 "NVMCTRL - Non-Volatile
Memory Controller": "NVM Write", "Page Buffer Clear", "Erase Row", "Lock Bits", and its register description)."""

from __future__ import annotations

import struct

import pytest

from host_emulator.image.harness import Asm, Harness, HarnessError, Program, stub

NVM = 0x4100_4000
STATUS, INTFLAG = NVM + 0x18, NVM + 0x14
KEY = 0xA5 << 8  # CTRLA.CMDEX
CMD_ER, CMD_WP, CMD_EAR, CMD_PBC = 0x02, 0x04, 0x05, 0x44
MANW = 1 << 7  # CTRLB
LOAD, PROGE, LOCKE = 1 << 1, 1 << 2, 1 << 3  # STATUS
READY, ERROR = 1 << 0, 1 << 1  # INTFLAG
PAGE, ROW = 64, 256
FREE = 0x8000  # a flash row the stub (at 0x2000) does not use
# the model's typical programming times (csrc/sam_nvmctrl.c): not the datasheet's maxima
T_ROW_ERASE_S, T_PAGE_WRITE_S = 0.85e-3, 0.35e-3


def flash(h: Harness, addr: int, n: int) -> bytes:
    return h.ram(addr, n)


def command(h: Harness, cmd: int, addr: int | None = None) -> None:
    if addr is not None:
        h.write("NVMCTRL.ADDR", addr >> 1)  # 22.8.8 ADDR: in 16-bit words
    h.write("NVMCTRL.CTRLA", KEY | cmd)


def erase(h: Harness, addr: int) -> None:
    command(h, CMD_ER, addr)


def test_erase_row_sets_the_row_to_ones_and_stalls_the_cpu():
    """Erase Row erases the 256-byte row addressed by ADDR (every byte 0xFF); the CPU, fetching from the NVM, waits
    until it is done (the AHB is stalled while the NVM is busy), so READY reads 1 at the next access."""
    h = Harness()
    assert flash(h, FREE, ROW) == bytes(ROW)  # the harness's flash starts as zeros
    h.write("NVMCTRL.ADDR", (FREE + 0x40) >> 1)  # any address inside the row
    h.write("NVMCTRL.CTRLA", KEY | CMD_ER)
    t_cmd = h.t_access
    assert h.read("NVMCTRL.INTFLAG") & READY
    assert h.t_access - t_cmd >= h.tu(T_ROW_ERASE_S)
    assert flash(h, FREE, ROW) == b"\xff" * ROW
    assert flash(h, FREE + ROW, 4) == bytes(4), "the next row is untouched"
    assert h.info().nvm_erases == 1 and h.read("NVMCTRL.STATUS") == 0


def test_write_page_programs_the_buffer_and_only_clears_bits():
    """Stores to flash load the page buffer (STATUS.LOAD, ADDR = the store's address); Write Page programs the page at
    ADDR, which can only clear bits (an erase sets them), then clears the buffer."""
    h = Harness()
    erase(h, FREE)
    h.write("NVMCTRL.CTRLB", MANW)
    h.write(FREE + 8, 0x0F0F_0F0F, 4)
    assert h.read("NVMCTRL.STATUS") & LOAD
    assert h.read("NVMCTRL.ADDR") == (FREE + 8) >> 1, "22.6.4: the address of each AHB write is stored in ADDR"
    assert flash(h, FREE + 8, 4) == b"\xff" * 4, "nothing is programmed before Write Page (MANW = 1)"
    command(h, CMD_WP)
    assert flash(h, FREE + 8, 4) == b"\x0f" * 4
    assert h.read("NVMCTRL.STATUS") & LOAD == 0
    h.write(FREE + 8, 0x00FF_00FF, 4)
    h.write(FREE + 12, 0x1234, 2)
    command(h, CMD_WP)
    assert flash(h, FREE + 8, 6) == bytes([0x0F, 0x00, 0x0F, 0x00, 0x34, 0x12])
    assert flash(h, FREE, 8) == b"\xff" * 8, "the rest of the page: the cleared buffer's ones"
    assert h.info().nvm_writes == 2


def test_automatic_page_write_on_the_last_location():
    """With CTRLB.MANW = 0 a write to the last location of the page buffer writes the page (automatic page write)."""
    h = Harness()
    erase(h, FREE)
    assert h.read("NVMCTRL.CTRLB") & MANW == 0
    words = [0x1111_0000 + k for k in range(PAGE // 4)]
    for k, w in enumerate(words[:-1]):
        h.write(FREE + 4 * k, w, 4)
    assert flash(h, FREE, PAGE) == b"\xff" * PAGE
    h.write(FREE + PAGE - 4, words[-1], 4)
    t = h.t_access
    assert flash(h, FREE, PAGE) == struct.pack(f"<{len(words)}I", *words)
    assert h.read("NVMCTRL.STATUS") & LOAD == 0
    assert h.t_access - t >= h.tu(T_PAGE_WRITE_S)


def test_page_buffer_clear():
    """Page Buffer Clear sets the buffer to ones: a Write Page after it programs nothing."""
    h = Harness()
    erase(h, FREE)
    h.write("NVMCTRL.CTRLB", MANW)
    h.write(FREE, 0, 4)
    command(h, CMD_PBC)
    assert h.read("NVMCTRL.STATUS") & LOAD == 0
    command(h, CMD_WP, FREE)
    assert flash(h, FREE, PAGE) == b"\xff" * PAGE


def test_a_command_without_the_key_is_a_programming_error():
    """CTRLA.CMDEX must be 0xA5 for the command to execute; otherwise STATUS.PROGE and INTFLAG.ERROR are set and
    nothing happens. The error bits are cleared by writing ones to them."""
    h = Harness()
    h.write("NVMCTRL.ADDR", FREE >> 1)
    h.write("NVMCTRL.CTRLA", 0x5A00 | CMD_ER)
    assert flash(h, FREE, 4) == bytes(4)
    assert h.read("NVMCTRL.STATUS") & PROGE and h.read("NVMCTRL.INTFLAG") & ERROR
    h.write("NVMCTRL.STATUS", PROGE)
    h.write("NVMCTRL.INTFLAG", ERROR)
    assert h.read("NVMCTRL.STATUS") == 0 and h.read("NVMCTRL.INTFLAG") == READY


def test_bootprot_protects_the_bootloader_section():
    """BOOTPROT (user row bits 2:0) protects the first rows: 2 = 8 KiB (the UF2 bootloader's size); an erase or
    write there sets STATUS.LOCKE and leaves the flash. The tier's boards start with BOOTPROT = 7 (nothing
    protected: the shipped XIAOs' fuse is not known), so the same erase then goes through."""
    h = Harness()
    erase(h, 0x1000)
    assert flash(h, 0x1000, 4) == b"\xff" * 4 and h.read("NVMCTRL.STATUS") == 0, "BOOTPROT = 7: no protection"
    h.write("NVMCTRL.CTRLB", MANW)
    h.set_user_row(bytes([0xF8 | 2]))
    h.write(0x1000, 0, 4)
    command(h, CMD_WP)
    erase(h, 0x1F00)
    assert flash(h, 0x1000, 4) == b"\xff" * 4 and flash(h, 0x1F00, 4) == bytes(4)
    assert h.read("NVMCTRL.STATUS") & LOCKE and h.read("NVMCTRL.INTFLAG") & ERROR
    h.write(STATUS, LOCKE, 4)  # bossac writes STATUS as a word: the reserved bytes are ignored
    assert h.read("NVMCTRL.STATUS") == LOAD, "LOCKE cleared; the refused page is still in the buffer"
    erase(h, 0x2100)  # the first row above the section
    assert flash(h, 0x2100, 4) == b"\xff" * 4


def test_lock_bits_from_the_user_row():
    """LOCK is loaded from the user row's lock bits (bits 63:48; 16 regions of 16 KiB); a 0 locks its region: an
    erase there sets STATUS.LOCKE."""
    h = Harness()
    assert h.read("NVMCTRL.LOCK") == 0xFFFF
    h.set_user_row(bytes([0xFF] * 6 + [0xFD, 0xFF]))  # region 1 (0x4000-0x7FFF) locked
    assert h.read("NVMCTRL.LOCK") == 0xFFFD
    erase(h, 0x4000)
    assert flash(h, 0x4000, 4) == bytes(4) and h.read("NVMCTRL.STATUS") & LOCKE
    erase(h, FREE)
    assert flash(h, FREE, 4) == b"\xff" * 4


def test_commands_not_modelled_are_errors_naming_them():
    h = Harness()
    with pytest.raises(HarnessError, match="NVM command 0x5 is not modelled"):
        command(h, CMD_EAR, 0x80_4000)


def _fault_returns(a: Asm) -> dict[int, str]:
    """A HardFault handler that returns past the faulting 16-bit instruction with R1 = 0xBAD (its stacked R1)."""
    a.label("hardfault")
    a.mov_from_sp(2)
    a.mem("ldr", 3, 2, 24)
    a.adds(3, 2)
    a.mem("str", 3, 2, 24)
    a.ldr_const(3, 0xBAD)
    a.mem("str", 3, 2, 4)
    a.bx_lr()
    a.pool()
    return {3: "hardfault"}


def test_a_byte_store_to_flash_faults():
    """Writes to the page buffer must be 16 or 32 bits: an 8-bit write is not allowed and causes a system exception
    (a HardFault); the buffer is not loaded."""
    h = Harness(program=stub(_fault_returns))
    erase(h, FREE)
    h.write(FREE, 0x12, 1)
    assert h.info().hardfaults == 1
    assert h.read("NVMCTRL.STATUS") & LOAD == 0
    assert flash(h, FREE, 4) == b"\xff" * 4


def _patchable(a: Asm) -> dict[int, str]:
    """Code alone on its flash row: `movs r1, #1; b .`, to be rewritten by a test."""
    a.align(ROW)
    a.label("patch")
    a.movs(1, 1)
    a.label("patch_done")
    a.b()
    return {}


def test_code_rewritten_in_flash_runs_as_rewritten():
    """Code the CPU already ran, erased and programmed anew through NVMCTRL, runs as programmed (no stale
    translation of the old contents survives)."""
    h = Harness(program=stub(_patchable))
    patch = h.program.labels["patch"]
    assert patch % ROW == 0 and patch > 0x2000
    assert h.call("patch", "patch_done") == 1
    erase(h, patch)
    h.write("NVMCTRL.CTRLB", MANW)
    h.write(patch, 0xE7FE_2102, 4)  # movs r1, #2; b .
    command(h, CMD_WP)
    assert flash(h, patch, 4) == bytes.fromhex("0221fee7")
    assert h.call("patch", "patch_done") == 2


def test_code_rewritten_through_nvmctrl_is_costed_from_its_new_bytes():
    """NVMCTRL's erase and write of the ELF's code (the tables' range) go through the one path that drops the
    block costs memoised from it and the tables themselves: the rewritten instruction is costed by the decoder from
    its new bytes (MOVS, 1 core cycle, becomes PUSH {r0-r7}, 9), not from the tables of what was loaded."""
    h = Harness(program=stub(_patchable))
    assert h.program.tables is not None
    patch = h.program.labels["patch"]

    def spent() -> int:
        h.call("patch", "patch_done")  # the NVM cache warm for the second run
        c0 = h.info().cycles
        h.call("patch", "patch_done")
        return h.info().cycles - c0

    before = spent()
    erase(h, patch)
    h.write("NVMCTRL.CTRLB", MANW)
    h.write(patch, 0xE7FE_B4FF, 4)  # push {r0-r7}; b .
    command(h, CMD_WP)
    assert spent() == before + 8


def _store_then_more(a: Asm) -> dict[int, str]:
    """`str r1, [r0]` followed by more of its block: `movs`, `movs`, `b` to a label of its own."""
    a.label("store")
    a.mem("str", 1, 0)
    a.movs(2, 0)
    a.movs(2, 0)
    a.b("stored")
    a.label("stored")
    a.b()
    return {}


@pytest.mark.parametrize("tables", [True, False])
def test_a_store_into_the_page_buffer_costs_what_a_store_to_sram_costs(tables):
    """The store Unicorn stops at is finished by the model and execution resumes after it: the rest of its block,
    charged when the block began, is refunded (it runs, and is charged, as a block of its own); the same when the
    block is costed by the decoder (no ELF tables: the bootloader's code, bossac's)."""
    p = stub(_store_then_more)
    if not tables:
        p = Program(**{**p.__dict__, "tables": None})
    h = Harness(program=p)
    h.write("NVMCTRL.CTRLB", MANW)
    spent = []
    for addr in (0x2000_1000, FREE, 0x2000_1004, FREE + 4):
        c0 = h.info().cycles
        h.call("store", "stored", r0=addr, r1=0x1234_5678)
        spent.append(h.info().cycles - c0)
    assert flash(h, FREE, 8) == bytes(8) and h.read("NVMCTRL.STATUS") & LOAD, "in the buffer, not yet written"
    assert spent[0] == spent[1] == spent[2] == spent[3] > 0, spent
