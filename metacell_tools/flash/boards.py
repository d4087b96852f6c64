"""Find Seeeduino XIAO SAMD21 boards by USB identity (pyserial list_ports, or a JSON file of fake ports)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from metacell_common.target.board import XIAO_PID_APP, XIAO_PID_BOOT, XIAO_VID  # noqa: F401 (the XIAO's USB ids)


class PortListError(ValueError):
    """The fake port listing is malformed."""


@dataclass(frozen=True)
class Port:
    device: str  # e.g. /dev/ttyACM3
    vid: int | None
    pid: int | None
    serial_number: str | None
    location: str = ""
    description: str = ""

    @property
    def is_xiao(self) -> bool:
        return self.vid == XIAO_VID and self.pid in (XIAO_PID_APP, XIAO_PID_BOOT)

    @property
    def in_bootloader(self) -> bool:
        return self.vid == XIAO_VID and self.pid == XIAO_PID_BOOT


def _int_field(entry: dict, key: str, where: str) -> int | None:
    val = entry.get(key)
    if val is None:
        return None
    if isinstance(val, bool):
        raise PortListError(f"{where}: {key} must be an integer or hex string, got {val!r}")
    if isinstance(val, int):
        return val
    if isinstance(val, str):
        try:
            return int(val, 16 if val.lower().startswith("0x") else 10)
        except ValueError:
            pass
    raise PortListError(f"{where}: {key} must be an integer or hex string, got {val!r}")


def ports_from_json(path: str | Path) -> list[Port]:
    """A JSON list of {device, vid, pid, serial_number[, location, description]}."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise PortListError(f"cannot read port listing {path}: {exc}") from exc
    if not isinstance(data, list):
        raise PortListError(f"{path}: expected a JSON list of ports")
    ports = []
    for i, entry in enumerate(data):
        where = f"{path}[{i}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("device"), str):
            raise PortListError(f"{where}: each port needs a string 'device'")
        sn = entry.get("serial_number")
        if sn is not None and not isinstance(sn, str):
            raise PortListError(f"{where}: serial_number must be a string")
        ports.append(
            Port(
                entry["device"],
                _int_field(entry, "vid", where),
                _int_field(entry, "pid", where),
                sn,
                str(entry.get("location") or ""),
                str(entry.get("description") or ""),
            )
        )
    return ports


def system_ports() -> list[Port]:
    """The serial ports the OS sees now."""
    from serial.tools import list_ports

    return [
        Port(p.device, p.vid, p.pid, p.serial_number, p.location or "", p.description or "")
        for p in list_ports.comports()
    ]


def port_lister(ports_json: str | Path | None = None) -> Callable[[], list[Port]]:
    """A zero-argument callable listing ports: the fake file (re-read each call) or the OS."""
    if ports_json is None:
        return system_ports
    return lambda: ports_from_json(ports_json)


def _natural(device: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", device)]


def xiao_ports(ports: list[Port]) -> list[Port]:
    """The XIAO SAMD21 boards among ports (application or bootloader mode), ttyACM2 < ttyACM10."""
    return sorted((p for p in ports if p.is_xiao), key=lambda p: _natural(p.device))
