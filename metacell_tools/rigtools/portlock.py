"""One reader per serial port: metacell_common.portlock (the emulator's serve uses it too), under its old name."""

from metacell_common.portlock import PortBusy, busy_text, claim, device_of, holders, release

__all__ = ["PortBusy", "busy_text", "claim", "device_of", "holders", "release"]
