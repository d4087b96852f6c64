"""The buffered SLCAN reader now lives in tools/rigtools/slcanbus.py (shared with the rig logger); kept as an alias."""

from tools.rigtools.slcanbus import BufferedSlcanBus, open_bus  # noqa: F401
