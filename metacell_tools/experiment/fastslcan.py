"""The buffered SLCAN reader now lives in metacell_tools/rigtools/slcanbus.py (shared with the rig logger); an alias."""

from metacell_tools.rigtools.slcanbus import BufferedSlcanBus, open_bus  # noqa: F401
