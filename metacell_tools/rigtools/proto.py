"""The laptop tools' name for protocol.wire (the rig's one wire definition, shared with the emulator)."""

from pathlib import Path

from protocol import definition as D  # noqa: F401
from protocol.wire import *  # noqa: F403
from protocol.wire import (  # noqa: F401
    _FMT,
    DBC_PATH,
    PROTOCOL_DIR,
    cell_address,
    cell_of_address,
    crc8,
    map_id,
)

ROOT = Path(__file__).resolve().parents[2]  # the repository (tests and tools find files relative to it)
