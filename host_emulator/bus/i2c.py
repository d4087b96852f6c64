"""I2C timing model (standard 100 kHz and fast 400 kHz mode) and the bus-limited full-lattice sample rate.

A transaction of n bytes after the address byte occupies the bus for

    t = (1 + 9 + 9 n + 1) / f + t_BUF

bits: START (counted as one bit period; the spec needs t_HD;STA >= 4.0/0.6 us), the
address byte plus its ACK (9), every data byte plus its ACK/NACK (9 each), STOP (one bit
period, t_SU;STO >= 4.0/0.6 us), then the bus-free time before the next START
(t_BUF >= 4.7 us at 100 kHz, 1.3 us at 400 kHz, I2C-bus specification UM10204 table 10).
An address NACK ends after the address byte: t = (1 + 9 + 1) / f + t_BUF.
Clock stretching by the secondaries is not modelled (the SAMD21 Wire secondary stretches
while its callbacks run; see docs/datapath.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from protocol import wire

T_BUF_S = {100_000: 4.7e-6, 400_000: 1.3e-6}


@dataclass(frozen=True)
class I2CTiming:
    hz: int = 400_000

    def __post_init__(self):
        if self.hz not in T_BUF_S:
            raise ValueError(f"I2C clock must be one of {sorted(T_BUF_S)} Hz, got {self.hz}")

    @property
    def bit_s(self) -> float:
        return 1.0 / self.hz

    def bits(self, nbytes: int) -> int:
        """Bit periods of a transaction with nbytes after the address (START, addr+ACK, data+ACKs, STOP)."""
        return 1 + 9 + 9 * nbytes + 1

    def transaction_s(self, nbytes: int) -> float:
        return self.bits(nbytes) * self.bit_s + T_BUF_S[self.hz]

    def nack_s(self) -> float:
        return self.bits(0) * self.bit_s + T_BUF_S[self.hz]

    def request_offset_s(self) -> float:
        """From START to the secondary's onRequest (after the address byte and its ACK)."""
        return (1 + 9) * self.bit_s


def lattice_rate_limit(hz: int = 400_000, cells: int | None = None, snapshot_len: int | None = None) -> float:
    """Full-lattice samples per second the bus allows: one snapshot read per cell, nothing else on the bus."""
    cells = wire.N_CELLS if cells is None else cells
    if snapshot_len is None:
        snapshot_len = wire.block_len("SNAPSHOT")
    return 1.0 / (cells * I2CTiming(hz).transaction_s(snapshot_len))
