"""`boards`' USB host as cdc_acm on a pty, without images: a client's open, speed and close become the line state
given to the board (DTR/RTS, line coding), the 1200-baud touch is kept from the firmware or forwarded by one switch,
and a re-enumeration (the host's counter) makes the port again."""

from __future__ import annotations

import json
import os
import termios
from dataclasses import dataclass, replace
from types import SimpleNamespace

from host_emulator.image.boards import APPLICATION, BOOTLOADER, Board, Boards, SambaFramer
from host_emulator.image.world import UsbDevice

APP = UsbDevice(
    0x2886, 0x802F, 0x200, 0x104, "Seeed", "Seeeduino XIAO", "ABC1", 0, 3, 2, 1, 0, 9600, False, False, True
)


@dataclass
class FakeWorld:
    """The World calls Boards makes, recorded: one board, configured, its device as `dev` says."""

    dev: UsbDevice = APP
    resets: int = 0
    transfers: int = 11
    out_bytes: int = 0  # bytes the device took (all of them, at once)

    def __post_init__(self) -> None:
        self.lines: list[tuple[int, bool, bool]] = []
        self.reset_asked = 0
        self.profiles: list[str] = []
        self.writes: list[bytes] = []

    def usb_attach(self, b: int, profile: str = "script") -> None:
        self.profiles.append(profile)

    def info(self, b: int):
        return SimpleNamespace(resets=self.resets)

    def usb_info(self, b: int):
        return SimpleNamespace(configured=1, control_transfers=self.transfers, out_bytes=self.out_bytes)

    def usb_device(self, b: int) -> UsbDevice:
        return self.dev

    def usb_read(self, b: int) -> bytes:
        return b""

    def usb_write(self, b: int, data: bytes) -> int:
        self.writes.append(bytes(data))
        self.out_bytes += len(data)
        return len(data)

    def usb_line(self, b: int, baud: int, dtr: bool, rts: bool) -> None:
        self.lines.append((baud, dtr, rts))

    def reset(self, b: int) -> None:
        self.reset_asked += 1


def rig(tmp_path, bootloader_problem: str | None = "no bootloader here"):
    w = FakeWorld()
    b = Board(0, 0, "cell 1", str(tmp_path / "ttyACM-mc01"), "FALLBACK")
    r = Boards(w, [b], tmp_path / "ports.json", bootloader_problem)
    r.service()
    return w, b, r


def client(link: str, baud: int) -> int:
    fd = os.open(link, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = getattr(termios, f"B{baud}")
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return fd


def test_open_speed_and_close_become_the_line_state(tmp_path):
    w, b, r = rig(tmp_path)
    assert w.profiles == ["linux"] and b.mode == APPLICATION and b.serial == "ABC1"  # the descriptor's serial
    assert w.lines == []  # a new port: 9600 baud, lines low, as cdc_acm's probe left them
    fd = client(b.link, 921600)
    r.service()
    assert w.lines == [(921600, True, True)]
    r.service()  # nothing changed: nothing sent
    assert w.lines == [(921600, True, True)]
    os.close(fd)
    r.service()
    assert w.lines[-1] == (921600, False, False)  # the close drops DTR and RTS, the speed kept
    r.close()


def test_touch_kept_from_the_firmware_without_the_bootloader(tmp_path, capsys):
    w, b, r = rig(tmp_path)
    fd = client(b.link, 1200)
    r.service()
    os.close(fd)
    r.service()
    # the open and close reach the board, 1200 baud does not (the firmware would erase its first row)
    assert w.lines == [(0, True, True), (0, False, False)]
    assert w.reset_asked == 1 and r.touches == 1 and b.port is None and b.comes_back_as == APPLICATION
    assert "1200-baud touch: no bootloader here" in capsys.readouterr().err
    r.close()


def test_touch_forwarded_with_the_bootloader(tmp_path):
    w, b, r = rig(tmp_path, None)
    fd = client(b.link, 1200)
    r.service()
    os.close(fd)
    r.service()
    r.service()  # taken once
    # as cdc_acm: DTR/RTS up, the coding 1200, DTR/RTS down: the firmware resets itself, nothing from outside
    assert w.lines == [(1200, True, True), (1200, False, False)]
    assert w.reset_asked == 0 and r.touches == 1 and b.port is not None and b.comes_back_as == BOOTLOADER
    # the board comes back on its own (the host counted a new enumeration): a new port, the mode its PID says
    w.dev = replace(APP, pid=0x002F, product="Seeeduino XIAO", enumerations=2, detaches=1)
    old = b.port
    r.service()
    assert b.mode == BOOTLOADER and b.port is not None and b.port is not old and b.enumerations == 2
    assert os.readlink(b.link) == b.port.path
    r.close()


def test_samba_writes_are_split_where_bossacs_calls_ended():
    f = SambaFramer()
    held = bytearray(b"N#V#S20004034,00000005#hello#w20004000,4#")
    parts = []
    while held:
        n = f.transfer(held)
        parts.append(bytes(held[:n]))
        del held[:n]
    assert parts == [b"N#", b"V#", b"S20004034,00000005#", b"hello", b"#", b"w20004000,4#"]
    # data comes in whole packets until its last one (a short packet would end the monitor's read), and what
    # follows a first piece continues the same write
    assert f.transfer(b"S0,00000100#") == 12 and not f.continues()
    assert f.transfer(b"x" * 100) == 64 and f.continues()
    assert f.transfer(b"x" * 36) == 0 and f.continues()
    assert f.transfer(b"x" * 192 + b"N#") == 192 and not f.continues()
    assert f.transfer(b"V") == 0 and f.transfer(b"N#") == 2


def test_bootloader_bytes_go_one_transfer_at_a_time(tmp_path):
    w, b, r = rig(tmp_path, None)
    w.dev = replace(APP, pid=0x002F, enumerations=2, detaches=1)
    r.service()  # it came back in its bootloader
    assert b.mode == BOOTLOADER
    fd = client(b.link, 921600)
    os.write(fd, b"S20004034,00000003#abcN#")
    r.service()
    w.transfers += 2  # the open's line state reached the board
    for _ in range(6):
        r.service()
    assert w.writes == [b"S20004034,00000003#", b"abc", b"N#"]
    os.close(fd)
    r.close()


def test_unplug_and_deaf_through_the_control_directory(tmp_path):
    w, b, r = rig(tmp_path, None)
    ctl = tmp_path / "ctl"
    ctl.mkdir()
    (ctl / "deaf-mc01").touch()
    r.control(ctl)
    assert b.deaf and not (ctl / "deaf-mc01").exists()
    fd = client(b.link, 1200)
    r.service()
    os.close(fd)
    r.service()
    assert r.touches == 0 and w.lines == [(0, True, True), (0, False, False)], "the touch is kept from it"
    (ctl / "unplug-mc01").touch()
    r.control(ctl)
    r.service()
    assert b.unplugged and b.port is None and not b.mode and json.loads((tmp_path / "ports.json").read_text()) == []
    r.close()
