"""Upload through the XIAO's bootloader with bossac: the 1200-baud touch, the bootloader's port, the bossac command.

What Seeed's core does for the XIAO (and PlatformIO's uploader with bossac 1.7), spelled out for Debian's bossac 1.9.1,
which must be told where the application goes (`--offset=0x2000`) or it writes over the bootloader. Ports come from
the same listing as everywhere in the tool (the OS's, or --ports-json re-read on each call), so an emulated board
behind a pty works in place of a USB one.
"""

from __future__ import annotations

import errno
import re
import shlex
import shutil
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from metacell_common.target.pio import packages_dir

from .boards import Port
from .toolchain import APP_OFFSET

TOUCH_BAUD = 1200  # Seeed's core resets into the bootloader when its CDC port is set to 1200 baud and DTR drops


def touch_1200(device: str) -> None:
    """The 1200-baud touch of an application's port: open at 1200 baud, drop DTR, close (OSError if it cannot)."""
    import serial  # pyserial

    port = serial.Serial(device, baudrate=TOUCH_BAUD)
    try:
        port.dtr = False
    except OSError as exc:  # a pty has no modem lines: its other side sees the 1200 baud and the close's hang-up
        if exc.errno not in (errno.EINVAL, errno.ENOTTY):
            raise
    finally:
        port.close()


def wait_for_port(
    serial: str,
    list_ports: Callable[[], list[Port]],
    timeout: float,
    bootloader: bool | None,
    poll: float = 0.25,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> Port | None:
    """The port of the board with this USB serial number in bootloader (or application; None: either) mode, once it
    is listed."""
    end = clock() + timeout
    while True:
        for p in list_ports():
            if p.serial_number == serial and p.is_xiao and bootloader in (None, p.in_bootloader):
                return p
        if clock() >= end:
            return None
        sleep(poll)


@dataclass(frozen=True)
class BossacUpload:
    """bossac writing one build's firmware.bin through the bootloader."""

    bossac: str
    firmware: Path  # the build's firmware.bin (made from firmware.elf beside it when the build left none)
    offset: int = APP_OFFSET

    def argv(self, port: str) -> tuple[str, ...]:
        """bossac 1.9.1: USB protocol (raw binary, no XMODEM; `-U true` of bossac 1.7 is an error here: "extra
        arguments found"), device info, erase from the offset, write, verify, reset into the new application."""
        return (
            self.bossac,
            f"--port={port}",
            "--usb-port=1",
            "--info",
            f"--offset=0x{self.offset:x}",
            "--erase",
            "--write",
            "--verify",
            "--reset",
            str(self.firmware),
        )

    def shell(self, port: str = "PORT") -> str:
        return shlex.join(self.argv(port))


def find_objcopy() -> str:
    """arm-none-eabi-objcopy: on PATH, else PlatformIO's toolchain package (the offline tree's or the core dir's)."""
    name = "arm-none-eabi-objcopy"
    in_pio = packages_dir() / "toolchain-gccarmnoneeabi" / "bin" / name
    return shutil.which(name) or (str(in_pio) if in_pio.is_file() else name)


def make_bin(firmware: Path, objcopy: str = "", run: Callable[..., Any] = subprocess.run) -> str:
    """Make firmware.bin from the firmware.elf beside it (PlatformIO makes both: a fallback); "" or why not."""
    elf = firmware.with_suffix(".elf")
    objcopy = objcopy or find_objcopy()
    if not elf.is_file():
        return f"the build left neither {firmware} nor {elf}"
    try:
        r = run([objcopy, "-O", "binary", str(elf), str(firmware)], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"the build left no {firmware.name}, and {objcopy} cannot make it from {elf}: {exc}"
    if r.returncode != 0 or not firmware.is_file():
        return f"the build left no {firmware.name}, and {objcopy} failed on {elf}: {str(r.stderr).strip()[:200]}"
    return ""


# PlatformIO's and SCons' framing around the real message: rules, the summary table, "*** [upload] Error 1"
_NOISE = re.compile(
    r"^([=\-*~_ ]+"
    r"|=+ \[(SUCCESS|FAILED|ERROR)\].*"
    r"|=+ \d+ (failed|succeeded).*"
    r"|\*\*\* \[.*\] Error \d+"
    r"|Environment\s+Status\s+Duration"
    r"|\S+\s+(SUCCESS|FAILED|IGNORED)\s+[\d:.]+)$"
)
_HINTS = (
    ("HTTPClientError", "PlatformIO tried to download a package: offline, see docs/hardware.md#flashing-offline"),
    ("Installing", "PlatformIO tried to install a package: offline, see docs/hardware.md#flashing-offline"),
    ("No device found on", "nothing answered bossac on that port: not this board's bootloader, or it left it"),
    ("extra arguments found", "this bossac does not take that command line: use Debian's bossa-cli 1.9"),
    ("Verify failed", "the flash does not hold what was written: try again, then suspect the board"),
)


def uploader_error(output: str, lines: int = 3, width: int = 200) -> str:
    """The uploader's own last meaningful lines (not the framing around them), with a hint for the known ones."""
    keep = [ln.strip()[:width] for ln in output.splitlines() if ln.strip() and not _NOISE.match(ln.strip())]
    text = " | ".join(keep[-lines:]) or "no output"
    hints = [h for pat, h in _HINTS if pat in text]
    return f"{text} ({hints[0]})" if hints else text
