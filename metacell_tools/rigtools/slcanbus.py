"""python-can's slcan interface with a buffered line reader, shared by the rig logger, the command tool and the
experiment runner (same commands, same frame parsing, ~20x fewer system calls).

python-can 4.x's `slcanBus._read` takes one byte per `read(1)` (a select and a read per
byte, ~22 per CELL_SAMPLE line): at the primary's 16 x 111 frames/s that is about half a
core here, and a reader that falls behind loses frames at the primary's USB queue (or the
emulator's pty backlog). `BufferedSlcanBus` overrides only `_read`: it takes every waiting
byte at once and hands out one line (ending in CR, or BEL for an error) per call, exactly
what `_read` returns; parsing stays python-can's `_recv_internal`. One deliberate
difference: undecodable bytes become U+FFFD (the line then fails python-can's parse as a
ValueError, which the runner counts as a corrupt line) instead of an "I/O error".

`open_bus` also enforces one reader per port (portlock: a port another program holds is refused with one line,
PortBusy; the port is locked while the bus is open).
"""

from __future__ import annotations

from typing import Any

import can
from can.exceptions import error_check
from can.interfaces.slcan import slcanBus

from metacell_common import portlock

try:
    from serial import Timeout
except ImportError:  # pragma: no cover - pyserial is a dependency of the slcan interface
    Timeout = None


class BufferedSlcanBus(slcanBus):
    """slcanBus whose `_read` reads all waiting bytes per system call."""

    _TERMINATORS = (slcanBus._OK[0], slcanBus._ERROR[0])

    def _line(self) -> str | None:
        buf = self._buffer
        ends = [i for i in (buf.find(slcanBus._OK), buf.find(slcanBus._ERROR)) if i >= 0]
        if not ends:
            return None
        i = min(ends) + 1
        text = bytes(buf[:i]).decode("ascii", errors="replace")
        del buf[:i]
        return text

    def _read(self, timeout: float | None) -> str | None:
        deadline = Timeout(timeout)
        with error_check("Could not read from serial device"):
            while True:
                line = self._line()
                if line is not None:
                    return line
                port = self.serialPortOrig
                chunk = port.read(max(1, port.in_waiting))  # waits at most the port timeout (1 ms)
                if chunk:
                    self._buffer.extend(chunk)
                elif deadline.expired():
                    return None


def open_bus(
    interface: str, channel: str, open_wait: float | None = None, plain: bool = False, bitrate: int | None = None
) -> can.BusABC:
    """The tools' bus: BufferedSlcanBus for slcan (unless plain), else can.Bus(interface, channel).

    A serial port held by another program raises portlock.PortBusy (one line) before anything is sent; the port
    stays locked until the bus shuts down."""
    kw: dict[str, Any] = {}
    if interface == "slcan" and open_wait is not None:
        kw["sleep_after_open"] = open_wait
    if bitrate is not None:
        kw["bitrate"] = bitrate
    lock = portlock.claim(channel) if interface == "slcan" else None
    try:
        if interface == "slcan" and not plain and hasattr(slcanBus, "_read") and Timeout is not None:
            bus: can.BusABC = BufferedSlcanBus(channel=channel, **kw)
        else:
            bus = can.Bus(interface=interface, channel=channel, **kw)
    except BaseException:
        portlock.release(lock)
        raise
    if lock is not None:
        shutdown = bus.shutdown

        def shutdown_and_unlock() -> None:
            try:
                shutdown()
            finally:
                portlock.release(lock)

        bus.shutdown = shutdown_and_unlock  # type: ignore[method-assign]
    return bus
