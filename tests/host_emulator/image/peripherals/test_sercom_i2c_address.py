"""SERCOM2 as I2C slave on the register-level harness: which 7-bit addresses it answers in each address mode
(CTRLB.AMODE: mask, two addresses, range), with the general call (ADDR.GENCEN), the automatic address acknowledge
(CTRLB.AACKEN), and the settings the model refuses (ten-bit addresses, the reserved AMODE). Every address is probed
on the bus against a predicate written from the datasheet's rule (DS40001882 28.6.3.1 "Address Match and Mask",
28.10.2 I2CS CTRLB, 28.10.9 I2CS ADDR; field positions from the CMSIS header the register table is made from)."""

from __future__ import annotations

import pytest

from host_emulator.image.harness import Harness, HarnessError

from .bench import bus_clock, sercom2_i2c_pins

SLAVE, MASTER = 0, 1  # board indices
ENABLE = 1 << 1
MODE_SLAVE, MODE_MASTER = 0x4 << 2, 0x5 << 2  # CTRLA.MODE
M_MB, M_SB = 1 << 0, 1 << 1  # I2CM.INTFLAG
S_PREC, S_AMATCH, S_DRDY = 1 << 0, 1 << 1, 1 << 2  # I2CS.INTFLAG
RXNACK, DIR, CLKHOLD = 1 << 2, 1 << 3, 1 << 7  # STATUS
CMD3 = 0x3 << 16  # CTRLB.CMD 3: the slave's acknowledge action; the master's STOP
ACKACT = 1 << 18  # CTRLB.ACKACT: NACK
AACKEN = 1 << 10  # I2CS.CTRLB.AACKEN
AMODE_POS = 14  # I2CS.CTRLB.AMODE[15:14]: 0 MASK, 1 2_ADDRS, 2 RANGE, 3 reserved
GENCEN = 1 << 0  # I2CS.ADDR.GENCEN
ADDR_POS, ADDRMASK_POS = 1, 17  # I2CS.ADDR.ADDR[10:1], ADDRMASK[26:17]
TENBITEN = 1 << 15  # I2CS.ADDR.TENBITEN
BUSSTATE_IDLE = 1 << 4
T = 10e-6  # SCL period at GCLK 1 MHz and BAUD 0 (plus the 125 ns rise time)
MASK, TWO_ADDRS, RANGE = 0, 1, 2


def bus(ctrlb: int, addr_reg: int) -> Harness:
    """A cell as the slave with CTRLB and ADDR as given (written before it is enabled), a primary as the master."""
    h = Harness(boards=("cell", "primary"))
    sercom2_i2c_pins(h, (SLAVE, MASTER))
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE, board=SLAVE)
    h.write("SERCOM2.I2CS.CTRLB", ctrlb, board=SLAVE)
    h.write("SERCOM2.I2CS.ADDR", addr_reg, board=SLAVE)
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE | ENABLE, board=SLAVE)
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER, board=MASTER)
    h.write("SERCOM2.I2CM.BAUD", 0, board=MASTER)
    h.write("SERCOM2.I2CM.CTRLA", MODE_MASTER | ENABLE, board=MASTER)
    h.advance(20e-6)
    h.write("SERCOM2.I2CM.STATUS", BUSSTATE_IDLE, board=MASTER)
    h.advance(20e-6)
    return h


def answered(h: Harness, ctrlb: int, a: int) -> bool:
    """The master writes to address a: True when the slave took it (AMATCH, SCL held), False when the master got
    MB with RXNACK and the slave saw nothing. The slave then refuses it (ACKACT NACK) and the master ends with STOP,
    so the bus is idle again for the next probe."""
    h.write("SERCOM2.I2CM.ADDR", a << 1, board=MASTER)
    h.advance(12 * T)
    amatch = bool(h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_AMATCH)
    if amatch:
        assert not h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB, f"0x{a:02x}: SCL not held after AMATCH"
        h.write("SERCOM2.I2CS.CTRLB", ctrlb | ACKACT | CMD3, board=SLAVE)
        h.advance(3 * T)
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB, f"0x{a:02x}: no MB"
    assert h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK, f"0x{a:02x}: acknowledged"
    h.write("SERCOM2.I2CM.CTRLB", CMD3, board=MASTER)
    h.advance(4 * T)
    h.write("SERCOM2.I2CS.INTFLAG", S_PREC, board=SLAVE)
    return amatch


def datasheet_match(amode: int, addr: int, second: int, gencen: bool, a: int) -> bool:
    """28.6.3.1: MASK, the bits set in ADDRMASK are left out of the comparison with ADDR; 2_ADDRS, ADDR or ADDRMASK;
    RANGE, from ADDRMASK (the lower limit) to ADDR (the upper limit), both included. 28.10.9: GENCEN, the general
    call address 0 as well."""
    if gencen and a == 0:
        return True
    if amode == MASK:
        return (a ^ addr) & ~second & 0x7F == 0
    if amode == TWO_ADDRS:
        return a in (addr, second)
    return second <= a <= addr


# (AMODE, ADDR.ADDR, ADDR.ADDRMASK, GENCEN): the second field is the mask, the second address or the lower limit
CASES = [
    (MASK, 0x42, 0x05, False),  # the mask, as before: 0x42, 0x43, 0x46, 0x47
    (TWO_ADDRS, 0x11, 0x6C, True),
    (RANGE, 0x30, 0x28, False),  # 0x28 to 0x30
    (RANGE, 0x7F, 0x70, True),
]


@pytest.mark.parametrize("amode,addr,second,gencen", CASES)
def test_each_address_mode_answers_exactly_the_addresses_of_the_datasheets_rule(amode, addr, second, gencen):
    ctrlb = amode << AMODE_POS
    h = bus(ctrlb, addr << ADDR_POS | second << ADDRMASK_POS | (GENCEN if gencen else 0))
    got = {a for a in range(128) if answered(h, ctrlb, a)}
    want = {a for a in range(128) if datasheet_match(amode, addr, second, gencen, a)}
    assert got == want
    assert (0 in got) == gencen


def test_automatic_address_acknowledge_no_amatch_no_stretch():
    """CTRLB.AACKEN (28.10.2): a matching address is acknowledged by the slave itself. The model sets no AMATCH
    and holds no SCL for it: the master's MB with RXNACK clear follows the address at once; STATUS.DIR tells the
    direction; the first data byte of a write sets DRDY (SCL held until the acknowledge action, as without
    AACKEN); a read sets DRDY (data wanted) right after the address. An address that does not match is still
    not acknowledged."""
    ctrlb = AACKEN  # AMODE 0
    h = bus(ctrlb, 0x42 << ADDR_POS)
    h.write("SERCOM2.I2CM.ADDR", 0x42 << 1, board=MASTER)
    h.advance(12 * T)
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB, "acknowledged without the slave's software"
    assert not h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    assert not h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & (S_AMATCH | S_DRDY)
    st = h.read("SERCOM2.I2CS.STATUS", board=SLAVE)
    assert not st & DIR and not st & CLKHOLD
    h.write("SERCOM2.I2CM.DATA", 0x5A, board=MASTER)
    h.advance(10 * T)
    assert h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_DRDY
    assert h.read("SERCOM2.I2CS.DATA", board=SLAVE) == 0x5A
    assert not h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB, "SCL held until the data's acknowledge"
    h.write("SERCOM2.I2CS.CTRLB", ctrlb | CMD3, board=SLAVE)
    h.advance(3 * T)
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_MB
    assert not h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    h.write("SERCOM2.I2CM.CTRLB", CMD3, board=MASTER)  # STOP
    h.advance(4 * T)
    assert h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_PREC

    h.write("SERCOM2.I2CM.ADDR", 0x42 << 1 | 1, board=MASTER)  # a read
    h.advance(12 * T)
    flags = h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE)
    assert flags & S_DRDY and not flags & S_AMATCH, "data wanted at once, no address interrupt"
    assert h.read("SERCOM2.I2CS.STATUS", board=SLAVE) & DIR
    h.write("SERCOM2.I2CS.DATA", 0xC3, board=SLAVE)
    h.advance(10 * T)
    assert h.read("SERCOM2.I2CM.INTFLAG", board=MASTER) & M_SB
    assert h.read("SERCOM2.I2CM.DATA", board=MASTER) == 0xC3
    h.write("SERCOM2.I2CM.CTRLB", CMD3 | ACKACT, board=MASTER)  # NACK and STOP
    h.advance(5 * T)
    assert h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & S_PREC

    h.write("SERCOM2.I2CS.INTFLAG", S_PREC | S_DRDY, board=SLAVE)
    h.write("SERCOM2.I2CM.ADDR", 0x43 << 1, board=MASTER)  # not its address
    h.advance(12 * T)
    assert h.read("SERCOM2.I2CM.STATUS", board=MASTER) & RXNACK
    assert not h.read("SERCOM2.I2CS.INTFLAG", board=SLAVE) & (S_AMATCH | S_DRDY)


def test_ten_bit_addressing_is_refused():
    """ADDR.TENBITEN: ten-bit slave addresses are not modelled; setting it in slave mode is an error naming it,
    not a bit stored without effect."""
    h = Harness(boards=("cell",))
    bus_clock(h, "SERCOM2")
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE)
    with pytest.raises(HarnessError, match=r"ADDR.TENBITEN.*not modelled"):
        h.write("SERCOM2.I2CS.ADDR", TENBITEN | 0x42 << ADDR_POS)


def test_the_reserved_address_mode_is_refused():
    """CTRLB.AMODE 3 is reserved (28.10.2): an error naming it."""
    h = Harness(boards=("cell",))
    bus_clock(h, "SERCOM2")
    h.write("SERCOM2.I2CS.CTRLA", MODE_SLAVE)
    with pytest.raises(HarnessError, match=r"AMODE 3.*reserved"):
        h.write("SERCOM2.I2CS.CTRLB", 3 << AMODE_POS)
