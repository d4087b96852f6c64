"""Boot from the reset vector through the XIAO's UF2 bootloader (WorldConfig.boot = "bootloader"): a blank board
reaches the bootloader's USB loop, cell 1's image is started at 0x2000 by the bootloader and answers `ID?` as in
direct boot, a reset that is not a power-on waits in the bootloader's double-tap window and returns, a second reset
in that window keeps the board in the bootloader, and MC_BOOTLOADER's messages. The bootloader's .bin is read from
MC_BOOTLOADER (these tests skip in one line without it); cell 1's image needs PlatformIO (MC_PIO_TREE)."""

from __future__ import annotations

import hashlib
import struct

import pytest

from host_emulator.image import bootloader
from host_emulator.image.world import World, WorldConfig, WorldError
from host_emulator.params import Params

from .conftest import images_or_skip

DOUBLE_TAP, MAGIC = 0x2000_7FFC, 0xF016_69EF  # the bootloader's double-tap word (the last word of SRAM)
RCAUSE_POR, RCAUSE_EXT, RCAUSE_SYST = 1 << 0, 1 << 4, 1 << 6
HANDOFF_S = 6.88e-3  # power-on to the application (measured: the bootloader's start-up at 1 MHz)
DOUBLE_TAP_WAIT_S = 0.900  # the bootloader's delay(500) at 1 MHz (measured)

# every register a blank board's bootloader touches from power-on to its USB loop, before a host enumerates it
# (docs/image-tier.md; the UF2 bootloader v3.7.0's main(), system_init() and USB_Open())
BLANK_REGISTERS = {
    "SCB.VTOR", "SBMATRIX.SFR[4]", "USB.DEVICE.QOSCTRL", "DMAC.QOSCTRL", "NVMCTRL.CTRLB",
    "PORT.Group[0].DIRSET", "PORT.Group[0].OUTCLR", "PORT.Group[0].OUTSET",
    "GCLK.GENDIV", "GCLK.GENCTRL", "GCLK.STATUS", "GCLK.CLKCTRL",
    "SYSCTRL.DFLLCTRL", "SYSCTRL.PCLKSR", "SYSCTRL.DFLLMUL", "SYSCTRL.DFLLVAL",
    "SysTick.LOAD", "SysTick.VAL", "SysTick.CTRL", "SCB.SHP[1]", "PM.APBBMASK",
    "PORT.Group[0].PINCFG[24]", "PORT.Group[0].PINCFG[25]", "PORT.Group[0].PMUX[12]",
    "USB.DEVICE.CTRLA", "USB.DEVICE.SYNCBUSY", "USB.DEVICE.PADCAL", "USB.DEVICE.DESCADD", "USB.DEVICE.CTRLB",
    "USB.DEVICE.INTFLAG", "USB.DEVICE.DeviceEndpoint[0].EPINTFLAG",
}  # fmt: skip


@pytest.fixture
def boot_bin() -> bytes:
    if bootloader.path() is None:
        pytest.skip(f"boot tests skipped: {bootloader.ENV} is not set")
    return bootloader.load()


@pytest.fixture(scope="module")
def cell_images():
    return images_or_skip(1, primary=False)


def word(w: World, addr: int) -> int:
    return struct.unpack("<I", w.read_mem(0, addr, 4))[0]


def in_bootloader(w: World) -> bool:
    return w.info(0).pc < bootloader.SIZE


def test_a_blank_board_reaches_the_bootloaders_usb_loop(boot_bin):
    w = World(Params(cells=1), None, primary=False, config=WorldConfig(boot="bootloader", blank=True))
    assert w.read_mem(0, 0, bootloader.SIZE) == boot_bin
    assert w.read_mem(0, bootloader.SIZE, 8) == b"\xff" * 8, "erased flash above the bootloader: no application"
    w.run_to(0.1)
    assert in_bootloader(w) and not w.info(0).lockup
    assert {name for name, _, _ in w.touched(0)} == BLANK_REGISTERS
    assert w.info(0).vtor == 0
    w.usb_attach(0)
    w.run_to(0.3)
    u = w.usb_info(0)
    assert u.enumerated and u.configured and not u.error
    assert in_bootloader(w) and w.info(0).resets == 1


def _identity(w: World, b: int, t: float) -> bytes:
    w.usb_attach(b)
    w.run_to(t)
    w.usb_dtr(b, True)
    w.run_to(t + 0.05)
    w.usb_read(b)
    w.usb_write(b, b"ID?\r\n")
    w.run_to(t + 0.15)
    return w.usb_read(b)


def test_cell_1_is_started_by_the_bootloader_and_answers_as_in_direct_boot(boot_bin, cell_images):
    direct = World(Params(cells=1), cell_images, primary=False)
    booted = World(Params(cells=1), cell_images, primary=False, config=WorldConfig(boot="bootloader"))
    assert booted.boot == "bootloader" and booted.read_mem(0, 0, bootloader.SIZE) == boot_bin
    booted.run_to(HANDOFF_S - 0.5e-3)
    assert in_bootloader(booted)
    booted.run_to(HANDOFF_S + 0.5e-3)
    assert not in_bootloader(booted), "the bootloader jumped to the application (power-on: no double-tap wait)"
    assert booted.info(0).vtor == 0x2000  # (the double-tap word is the application's stack from here on)
    # what the bootloader leaves behind for the application (a direct boot starts it from the reset values)
    assert booted.register(0, "NVMCTRL.CTRLB") == 0x80 and booted.register(0, "USB.DEVICE.QOSCTRL") == 0x0A
    want = _identity(direct, 0, 2.5)
    assert want == b"MC role=cell addr=0x10 cell=1 fw=1.0\r\n"
    assert _identity(booted, 0, 2.5) == want
    assert booted.info(0).resets == 1 and booted.info(0).reset_cause == RCAUSE_POR


def test_a_reset_waits_in_the_double_tap_window_and_returns(boot_bin, cell_images):
    w = World(Params(cells=1), cell_images, primary=False, config=WorldConfig(boot="bootloader"))
    w.run_to(0.5)
    assert not in_bootloader(w)
    w.fault("hardfault", 0.5, board=0)  # the application's HardFault handler resets the chip (SYSRESETREQ)
    w.run_to(0.52)
    assert w.info(0).resets == 2 and w.info(0).reset_cause == RCAUSE_SYST
    assert in_bootloader(w) and word(w, DOUBLE_TAP) == MAGIC, "waiting for a second reset"
    w.run_to(0.5 + DOUBLE_TAP_WAIT_S - 0.02)
    assert in_bootloader(w)
    w.run_to(0.5 + DOUBLE_TAP_WAIT_S + 0.02)
    assert not in_bootloader(w) and w.info(0).vtor == 0x2000, "the application runs again"


def test_a_second_reset_in_the_window_keeps_the_board_in_the_bootloader(boot_bin, cell_images):
    w = World(Params(cells=1), cell_images, primary=False, config=WorldConfig(boot="bootloader"))
    w.fault("reset_button", 0.5, board=0)
    w.fault("reset_button", 0.8, board=0)  # the double tap
    w.run_to(0.6)
    assert w.info(0).reset_cause == RCAUSE_EXT and word(w, DOUBLE_TAP) == MAGIC
    w.run_to(2.5)
    info = w.info(0)
    assert info.resets == 3 and info.reset_cause == RCAUSE_EXT
    assert in_bootloader(w) and word(w, DOUBLE_TAP) == 0, "it stays in the bootloader (the word consumed)"


def test_mc_bootloader_unset_is_one_line(monkeypatch):
    monkeypatch.delenv(bootloader.ENV, raising=False)
    with pytest.raises(bootloader.BootloaderError) as e:
        bootloader.load()
    assert str(e.value).startswith(f"the bootloader is not available: set {bootloader.ENV} to ")
    assert "\n" not in str(e.value)
    with pytest.raises(WorldError, match="the bootloader is not available"):
        World(Params(cells=1), None, primary=False, config=WorldConfig(boot="bootloader", blank=True))


def test_without_mc_bootloader_an_application_boots_directly(monkeypatch, capsys, cell_images):
    monkeypatch.delenv(bootloader.ENV, raising=False)
    w = World(Params(cells=1), cell_images, primary=False, config=WorldConfig(boot="bootloader"))
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("the bootloader is not available") and "directly" in err[0]
    assert w.boot == "direct" and w.info(0).vtor == 0x2000


def test_another_file_is_refused_naming_its_hash(monkeypatch, tmp_path):
    fake = tmp_path / "boot.bin"
    fake.write_bytes(bytes(bootloader.SIZE))
    monkeypatch.setenv(bootloader.ENV, str(fake))
    digest = hashlib.sha256(bytes(bootloader.SIZE)).hexdigest()
    with pytest.raises(bootloader.BootloaderError) as e:
        bootloader.load()
    msg = str(e.value)
    assert digest in msg and "refused" in msg and "\n" not in msg
    with pytest.raises(WorldError, match=digest):
        World(Params(cells=1), None, primary=False, config=WorldConfig(boot="bootloader", blank=True))


def test_the_decoder_costs_the_instruction_a_literal_pool_hides(boot_bin):
    """The block the bootloader executes at 0xdc follows literal data that a linear sweep reads as one 32-bit
    instruction at 0xda (not an ARMv6-M one); the decoder (csrc/sam_cost.c) starts where execution does and times
    it, so no sweep of the .bin is needed."""
    from host_emulator.image import runtime

    ffi, lib = runtime.load()
    o = ffi.new("sam_insn_cost_t *")
    assert lib.sam_cost_insn(*struct.unpack_from("<HH", boot_bin, 0xDA), o) == -1
    assert lib.sam_cost_insn(*struct.unpack_from("<HH", boot_bin, 0xDC), o) == 0 and o.core >= 1
