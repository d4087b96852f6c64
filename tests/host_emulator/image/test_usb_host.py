"""The laptop's USB host as Linux's cdc_acm: the Linux enumeration profile (ids and strings the boards' own descriptors
give), the CDC interfaces chosen by class, the line state reaching the firmware, the re-enumeration counter."""

from __future__ import annotations

import struct

import pytest

from host_emulator.image import runtime
from host_emulator.image.world import World
from host_emulator.params import Params

XIAO_VID, XIAO_PID_APP = 0x2886, 0x802F
LINE_INFO = "_ZL12_usbLineInfo"  # the Arduino core's CDC line coding: dwDTERate, stop, parity, bits, lineState
UP_S = 2.5  # the images enumerate at ~2.12 s


def chip_serial(index: int) -> str:
    """The serial string the Seeed core makes of the chip's serial number words (csrc/sam_world.c: unique per board)."""
    words = (0x4D43584F, 0x49414F00 + index, 0x53414D44, 0x3231AA00 + index)
    return "".join(f"{w:08X}" for w in words)


def run(w: World, dt: float) -> None:
    end = w.t + dt
    while w.t < end - 1e-9:
        w.run_to(min(end, w.t + 0.01))


def line_info(w: World, b: int) -> tuple[int, int]:
    """(baud, lineState) as the board's firmware holds them."""
    raw = w.read_mem(b, w.boards[b].image.symbol(LINE_INFO), 8)
    baud, _stop, _parity, _bits, state = struct.unpack("<IBBBB", raw)
    return baud, state


@pytest.fixture(scope="module")
def world(images):
    """Cell 1 under the Linux profile, the primary under the tier's script (the default), both enumerated."""
    w = World(Params(cells=1), images)
    w.usb_attach(0, "linux")
    w.usb_attach(1)
    run(w, UP_S)
    assert w.usb_info(0).configured and w.usb_info(1).configured
    return w


@pytest.mark.slow
def test_linux_profile_reads_the_boards_descriptors(images):
    """Both applications (a cell's and the primary's) enumerate under the Linux profile as the XIAO's Seeed core
    describes itself: VID:PID 2886:802F, "Seeed", "Seeeduino XIAO", the chip's serial number (unique per board);
    the CDC data endpoints and the comm interface the script profile also finds."""
    w = World(Params(cells=1), images)
    for b in w.boards:
        w.usb_attach(b.index, "linux")
    run(w, UP_S)
    for b in w.boards:
        d = w.usb_device(b.index)
        assert (d.vid, d.pid) == (XIAO_VID, XIAO_PID_APP), b.name
        assert (d.manufacturer, d.product, d.serial) == ("Seeed", "Seeeduino XIAO", chip_serial(b.index)), b.name
        assert (d.comm_if, d.data_in, d.data_out, d.enumerations, d.detaches) == (0, 3, 2, 1, 0), b.name
        assert d.described and d.baud == 9600 and not d.dtr and not d.rts  # cdc_acm's probe: 9600, lines low
        # device, address, device, configuration (9 then all), strings 0, iProduct, iManufacturer, iSerialNumber,
        # SET_CONFIGURATION, the probe's line coding
        assert w.usb_info(b.index).control_transfers == 11 and not w.usb_info(b.index).error
        assert line_info(w, b.index) == (9600, 0)
    assert not [n for n in w.notes() if "USB host" in n]


@pytest.mark.slow
def test_script_profile_is_unchanged(world):
    """The default profile: the tier's six enumeration transfers, no strings, no line coding until the port opens."""
    d = world.usb_device(1)
    assert (d.vid, d.pid, d.manufacturer, d.serial, d.baud) == (XIAO_VID, XIAO_PID_APP, "", "", 0)
    assert world.usb_info(1).control_transfers == 6


@pytest.mark.slow
def test_line_coding_and_control_lines_reach_the_firmware(world):
    """cdc_acm's requests from the laptop's line state: an open at 921600 (DTR and RTS up, then the coding), the
    close (lines down, the speed kept), baud 0 keeps the speed: the Arduino core's CDC sees each."""
    before = int(world.usb_info(0).control_transfers)
    world.usb_line(0, 921600, True, True)
    run(world, 0.01)
    assert line_info(world, 0) == (921600, 3)
    assert int(world.usb_info(0).control_transfers) == before + 2
    d = world.usb_device(0)
    assert (d.baud, d.dtr, d.rts) == (921600, True, True)
    world.usb_line(0, 0, False, False)
    run(world, 0.01)
    assert line_info(world, 0) == (921600, 0)
    assert int(world.usb_info(0).control_transfers) == before + 3
    world.usb_line(0, 0, False, False)  # nothing changed: nothing sent
    world.usb_line(0, 57600, False, True)  # RTS alone, then a new speed
    run(world, 0.01)
    assert line_info(world, 0) == (57600, 2)
    assert int(world.usb_info(0).control_transfers) == before + 5
    world.usb_line(0, 9600, False, False)
    run(world, 0.01)
    assert line_info(world, 0) == (9600, 0)


@pytest.mark.slow
def test_re_enumeration_is_counted_and_starts_a_new_tty(world):
    """A reset: the device leaves (detaches + 1) and enumerates again (enumerations + 1) with its descriptors read
    again; the line state starts over from cdc_acm's probe (9600, lines low) whatever the laptop had set."""
    world.usb_line(0, 115200, True, True)
    run(world, 0.01)
    assert line_info(world, 0) == (115200, 3)
    d0 = world.usb_device(0)
    world.reset(0)
    run(world, 0.01)
    gone = world.usb_device(0)
    assert gone.detaches == d0.detaches + 1 and not world.usb_info(0).configured
    run(world, UP_S)
    d = world.usb_device(0)
    assert world.usb_info(0).configured
    assert (d.enumerations, d.detaches) == (d0.enumerations + 1, d0.detaches + 1)
    assert (d.serial, d.pid, d.baud, d.dtr, d.rts) == (chip_serial(0), XIAO_PID_APP, 9600, False, False)
    assert line_info(world, 0) == (9600, 0)


@pytest.mark.slow
def test_usb_attach_refuses_an_unknown_profile_or_a_second_attach(world):
    with pytest.raises(ValueError, match="profile"):
        world.usb_attach(0, "windows")
    with pytest.raises(ValueError, match="already attached"):
        world.usb_attach(0, "linux")


def composite_config() -> bytes:
    """The XIAO bootloader's configuration (plan 2.3): IAD, CDC comm (if0, interrupt 0x83), CDC data (if1, bulk 0x81,
    0x02), mass storage (if2, bulk 0x84, 0x05), HID (if3) and vendor (if4) with interrupt endpoints."""

    def iface(n, cls, sub, proto, neps):
        return bytes([9, 4, n, 0, neps, cls, sub, proto, 0])

    def ep(addr, attr):
        return bytes([7, 5, addr, attr, 64, 0, 0 if attr == 2 else 1])

    body = bytes([8, 0x0B, 0, 2, 2, 2, 1, 0])  # IAD over if0, if1
    body += iface(0, 2, 2, 1, 1) + bytes([5, 0x24, 0, 0x10, 1]) + ep(0x83, 3)
    body += iface(1, 0x0A, 0, 0, 2) + ep(0x81, 2) + ep(0x02, 2)
    body += iface(2, 8, 6, 0x50, 2) + ep(0x84, 2) + ep(0x05, 2)
    body += iface(3, 3, 0, 0, 2) + ep(0x86, 3) + ep(0x06, 3)
    body += iface(4, 0xFF, 0, 0, 2) + ep(0x87, 3) + ep(0x07, 3)
    total = 9 + len(body)
    return bytes([9, 2, total & 0xFF, total >> 8, 5, 1, 0, 0x80, 50]) + body


def test_cdc_endpoints_by_interface_class():
    """A composite device's CDC data endpoints are its class-0x0A interface's, not its last bulk pair (the mass
    storage's); the comm interface (class requests' wIndex) is the ACM one; a configuration with no data interface
    keeps the last bulk pair."""
    ffi, lib = runtime.load()
    out = ffi.new("int32_t[3]")

    def parse(cfg: bytes):
        rc = lib.sam_usb_parse_config(cfg, len(cfg), out, out + 1, out + 2)
        return None if rc else tuple(out)

    cfg = composite_config()
    assert parse(cfg) == (0, 1, 2)
    # the comm interface numbered 3 and the data interface after it
    moved = cfg.replace(bytes([9, 4, 0, 0, 1, 2, 2, 1, 0]), bytes([9, 4, 3, 0, 1, 2, 2, 1, 0]))
    assert parse(moved) == (3, 1, 2)
    no_data = cfg.replace(bytes([9, 4, 1, 0, 2, 0x0A]), bytes([9, 4, 1, 0, 2, 0xFF]))
    assert parse(no_data) == (0, 4, 5)
    assert parse(bytes([9, 2, 9, 0, 0, 1, 0, 0x80, 50])) is None
