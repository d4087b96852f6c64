"""SERCOM2 in I2C on the register-level harness: a primary board masters the bus, a cell board answers as a
slave, both driven only through their registers; address match, data, acknowledge and stop flags against the
SAMD21 datasheet (Microchip DS40001882, chapter 28 "SERCOM I2C - Inter-Integrated Circuit")."""

from __future__ import annotations

from host_emulator.image.harness import Harness

from .bench import sercom2_i2c_pins

SLAVE, MASTER = 0, 1  # board indices
ADDR = 0x42
ENABLE = 1 << 1
MODE_SLAVE, MODE_MASTER = 0x4 << 2, 0x5 << 2  # CTRLA.MODE
M_MB, M_SB = 1 << 0, 1 << 1  # I2CM.INTFLAG
S_PREC, S_AMATCH, S_DRDY = 1 << 0, 1 << 1, 1 << 2  # I2CS.INTFLAG
RXNACK, DIR = 1 << 2, 1 << 3  # STATUS
CMD_ACK = 0x3 << 16  # I2CS.CTRLB.CMD 3: the acknowledge action (ACKACT 0: ACK)
CMD_STOP = 0x3 << 16  # I2CM.CTRLB.CMD 3: (acknowledge action,) then STOP
ACKACT = 1 << 18
BUSSTATE_IDLE = 1 << 4
T = 10e-6  # SCL period at GCLK 1 MHz and BAUD 0: 10 counts (28.6.2.4.1 Clock Generation), plus the rise time


def bus() -> Harness:
    h = Harness(boards=("cell", "primary"))
    sercom2_i2c_pins(h, (SLAVE, MASTER))
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE, board=SLAVE)
    h.write("SERCOM2.I2CS.ADDR", ADDR << 1, board=SLAVE)
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE | ENABLE, board=SLAVE)
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER, board=MASTER)
    h.write("SERCOM2.I2CM.BAUD", 0, board=MASTER)
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER | ENABLE, board=MASTER)
    h.advance(20e-6)
    h.write("SERCOM2.I2CM.STATUS", BUSSTATE_IDLE, board=MASTER)  # the bus state forced to idle
    h.advance(20e-6)
    return h


def master_flags(h: Harness) -> int:
    return h.read("SERCOM2.I2CM.INTFLAG", board=MASTER)


def slave_flags(h: Harness) -> int:
    return h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE)


def test_a_write_transaction_address_match_data_and_stop():
    """DS40001882 28.6.2.4 I2C Master Operation and 28.6.2.5 I2C Slave Operation (Figure "I2C Slave Behavioral
    Diagram"): the address sets the slave's AMATCH (STATUS.DIR 0: a master write) and the slave holds SCL until
    its acknowledge action (CTRLB.CMD = 3); the master's MB follows with RXNACK clear; a data byte sets the
    slave's DRDY with DATA; the master's STOP (CMD = 3) sets the slave's PREC and the bus goes idle."""
    h = bus()
    assert slave_flags(h) == 0 and master_flags(h) == 0
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1, board=MASTER)
    h.advance(12 * T)
    assert slave_flags(h) & S_AMATCH
    assert not h.read("SERCOM2.I2CS.STATUS", board=SLAVE) & DIR
    assert not master_flags(h) & M_MB, "SCL held by the slave until it acknowledges"
    h.write("SERCOM2.I2CS.CTRLB", CMD_ACK, board=SLAVE)
    assert not slave_flags(h) & S_AMATCH, "the command clears AMATCH"
    h.advance(3 * T)
    assert master_flags(h) & M_MB
    assert not h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    h.write("SERCOM2.I2CM.DATA", 0x5A, board=MASTER)
    assert not master_flags(h) & M_MB, "writing DATA clears MB"
    h.advance(10 * T)
    assert slave_flags(h) & S_DRDY
    assert h.read("SERCOM2.I2CS.DATA", board=SLAVE) == 0x5A
    h.write("SERCOM2.I2CS.CTRLB", CMD_ACK, board=SLAVE)
    h.advance(3 * T)
    assert master_flags(h) & M_MB and not h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    h.write("SERCOM2.I2CM.CTRLB", CMD_STOP, board=MASTER)
    h.advance(4 * T)
    assert slave_flags(h) & S_PREC
    assert h.read("SERCOM2.I2CM.STATUS", board=MASTER) >> 4 & 3 == 1  # BUSSTATE IDLE


def test_an_address_nobody_answers_gives_mb_with_rxnack():
    """DS40001882 28.6.2.4.2 (Transmitting Address Packets): when no slave acknowledges the address, MB is set
    and STATUS.RXNACK is one; a slave with another address sees no AMATCH."""
    h = bus()
    h.write("SERCOM2.I2CM.ADDR", (ADDR + 1) << 1, board=MASTER)
    h.advance(14 * T)
    assert master_flags(h) & M_MB
    assert h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    assert not slave_flags(h) & S_AMATCH


def test_a_read_transaction_slave_data_reaches_the_master():
    """DS40001882 28.6.2.5 I2C Slave Operation, master read: AMATCH with STATUS.DIR 1; after the acknowledge the
    slave's DRDY asks for data; the byte written to the slave's DATA sets the master's SB with it in DATA
    (28.6.2.4 Receiving Data Packets); the master's NACK and STOP end it with the slave's PREC."""
    h = bus()
    h.write("SERCOM2.I2CM.ADDR", ADDR << 1 | 1, board=MASTER)
    h.advance(12 * T)
    assert slave_flags(h) & S_AMATCH and h.read("SERCOM2.I2CS.STATUS", board=SLAVE) & DIR
    h.write("SERCOM2.I2CS.CTRLB", CMD_ACK, board=SLAVE)
    h.advance(3 * T)
    assert slave_flags(h) & S_DRDY
    h.write("SERCOM2.I2CS.DATA", 0xC3, board=SLAVE)
    h.advance(10 * T)
    assert master_flags(h) & M_SB
    assert h.read("SERCOM2.I2CM.DATA", board=MASTER) == 0xC3
    h.write("SERCOM2.I2CM.CTRLB", CMD_STOP | ACKACT, board=MASTER)
    h.advance(5 * T)
    assert slave_flags(h) & S_PREC
