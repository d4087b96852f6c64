"""The rig's wiring of a cell board (a Seeeduino XIAO): which SAMD21 pin drives or reads which part.

This is the hardware, not the firmware's idea of it: the image tier (host_emulator/image/board.py) drives the plant
from these pins and feeds the encoders into them, so firmware that drives another pin moves nothing. It is the "Cell
wiring" table of docs/hardware.md (and README.md's summary of it); tests/host_emulator/image/test_board.py compares
them, and the firmware's pins (src/cell/cell_config.h through the XIAO variant's pin table) with this.
"""

from __future__ import annotations

import re

# signal -> SAMD21 port pin
CELL_WIRING = {
    "nsleep": "PA02",  # D0: nSLEEP of both DRV8874
    "ph_alpha": "PA04",  # D1: PH of the alpha driver
    "en_alpha": "PA10",  # D2: EN of the alpha driver (PWM)
    "en_beta": "PA11",  # D3: EN of the beta driver (PWM)
    "sda": "PA08",  # D4: bus SDA
    "scl": "PA09",  # D5: bus SCL
    "ph_beta": "PB08",  # D6: PH of the beta driver
    "enc_alpha_a": "PB09",  # D7: alpha encoder channel A
    "enc_alpha_b": "PA07",  # D8: alpha encoder channel B
    "enc_beta_a": "PA05",  # D9: beta encoder channel A
    "enc_beta_b": "PA06",  # D10: beta encoder channel B
}
# the primary shares the bus pins (its other pins are unconnected)
PRIMARY_WIRING = {"sda": "PA08", "scl": "PA09"}
# the SERCOM on the bus: SDA and SCL are its PAD0 and PAD1 (docs/hardware.md: "I2C secondary (SERCOM2)")
BUS_SERCOM = "SERCOM2"


_PIN = re.compile(r"P([AB])([0-2][0-9]|3[01])", re.ASCII)


def pin_number(name: str) -> int:
    """ "PA10" -> 10, "PB09" -> 41 (the runtime's numbering: PA00..PA31 = 0..31, PB00..PB31 = 32..63)."""
    m = _PIN.fullmatch(name)
    if m is None:
        raise ValueError(f"{name!r}: expected a SAMD21 port pin such as PA10 or PB09")
    return (0 if m.group(1) == "A" else 32) + int(m.group(2))
