"""The chip's and the cell board's figures: the SAMD21G18A's clock, flash and memory map, the cell's encoders and
motors at full supply (the highest encoder edge rate) and the board's USB identities. fwcheck's CPU budget, the image
tier and the flash tool use them."""

from __future__ import annotations

import math

F_CPU_HZ = 48_000_000
FLASH_SIZE = 0x40000  # SAMD21G18A: 256 KiB of flash (SAM_FLASH_SIZE in the image tier's C)
#: Address ranges (start, end) of the SRAM, the flash and the single-cycle IOBUS (PORT) of the SAMD21G18A.
SRAM = (0x2000_0000, 0x2000_8000)
FLASH = (0x0000_0000, 0x0004_0000)
IOBUS = (0x6000_0000, 0x6000_0200)

# Highest encoder edge rate: no-load speed constant 49.8 rad/(V s) at the 5.86 V supply,
# 400 counts (edges of both channels) per revolution, two encoders per cell.
NO_LOAD_RAD_PER_V_S = 49.8
SUPPLY_V = 5.86
COUNTS_PER_REV = 400
ENCODERS = 2
TICK_HZ = 2000  # the cell's control tick (platformio.ini MC_CTRL_RATE_HZ)

# Seeed's board definition for the XIAO SAMD21 (hwids): the application's USB id and the UF2 bootloader's. The USB
# serial number is the chip's unique id, so it names the board whatever /dev/ttyACM* it lands on.
XIAO_VID = 0x2886
XIAO_PID_APP = 0x802F
XIAO_PID_BOOT = 0x002F


def max_edge_rate_hz() -> float:
    """Encoder interrupts per second of one cell at no-load speed (both encoders)."""
    rev_s = NO_LOAD_RAD_PER_V_S * SUPPLY_V / (2 * math.pi)
    return rev_s * COUNTS_PER_REV * ENCODERS
