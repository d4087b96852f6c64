"""PRIMARY_HEALTH: the compiled primary sends what the glue reports (reset cause, USB bytes lost, bus recoveries), the
shipped DBC decodes it, and the logger counts and shows it."""

import struct

import can
from hypothesis import given
from hypothesis import strategies as st

from host_emulator.bus.rig import make_rig
from metacell_tools.rigtools import proto
from metacell_tools.rigtools.logger import SampleDecoder, reset_cause_names

HEALTH = proto.FRAMES["PRIMARY_HEALTH"]["base"]


def health_frames(rig, seconds):
    out = []
    for _ in range(round(seconds / 0.02)):
        rig.advance_to(rig.t_us + 20_000)
        out += [bytes(d) for fid, d in rig.frames() if fid == HEALTH]
    return out


def test_health_frame_carries_what_the_glue_reported():
    rig, _ = make_rig("exp5_rest")
    lib = rig.lib
    lib.mc_primary_set_reset_cause(rig.p, lib.MC_RCAUSE_WDT)
    lost = [700, 64, 2**32 - 10]  # the last one saturates
    lib.mc_primary_usb_lost(rig.p, lost[0])
    lib.mc_primary_usb_lost(rig.p, lost[1])
    for _ in range(3):
        lib.mc_primary_bus_reset(rig.p)
    first = health_frames(rig, 1.1)
    assert len(first) == 1
    # independent decode: the definition's signal list as a struct format
    fmt, names = proto.layout(proto.FRAMES["PRIMARY_HEALTH"]["signals"])
    d = dict(zip(names, struct.unpack(fmt, first[0])))
    assert d == {"reset_cause": 1 << proto.D.RESET_CAUSE["WDT"], "usb_lost": 764, "bus_reset": 3, "usb_fail": 2}
    # the shipped DBC (generated from the same definition) agrees
    assert proto.database().decode_message(HEALTH, first[0], decode_choices=False) == d
    lib.mc_primary_usb_lost(rig.p, lost[2])
    (second,) = health_frames(rig, 1.0)
    assert struct.unpack(fmt, second)[1] == 2**32 - 1


def test_logger_reports_usb_loss_and_a_watchdog_reset():
    said = []
    dec = SampleDecoder(report=said.append)

    def feed(cause, lost):
        data = struct.pack("<BIHB", cause, lost, 0, 0)
        dec.feed(can.Message(arbitration_id=HEALTH, data=data, is_extended_id=False, timestamp=1.0))

    feed(0x20, 0)
    feed(0x20, 0)
    feed(0x20, 500)
    feed(0x20, 500)
    feed(0x20, 1200)
    assert dec.usb_lost == 1200 and dec.primary_reset_cause == ["WDT"]
    assert sum("last reset WDT" in s for s in said) == 1
    assert [s for s in said if "bytes of output lost" in s] == [
        "primary: 500 bytes of output lost at its USB port (500 since boot; the reader stalled)",
        "primary: 700 bytes of output lost at its USB port (1200 since boot; the reader stalled)",
    ]
    assert reset_cause_names(0x11) == ["POR", "EXT"]


class CoreBank:
    """The SAMD21 core's IN endpoint for one-packet writes (USBCore.cpp USBDeviceClass::send), written from its
    source: a write waits for the armed packet to be read; on the 70 ms timeout it zeroes that packet's byte count
    (a zero-length packet goes instead) and fails, and later writes fail at once until the host has read."""

    def __init__(self):
        self.armed: int | None = None  # bytes of the armed packet (0: the zero-length one), None: bank free
        self.timed_out = False
        self.delivered = self.zeroed = 0

    def host_reads(self):
        if self.armed is not None:
            self.delivered += self.armed
            self.armed = None

    def write(self, n: int, host_reading: bool) -> int:
        if host_reading:
            self.host_reads()
        if self.armed is not None:
            self.timed_out = True
            self.zeroed += self.armed
            self.armed = 0
            return -1
        self.timed_out = False
        self.armed = n
        if host_reading:
            self.host_reads()
        return n


@given(st.lists(st.tuples(st.integers(1, 64), st.booleans()), max_size=60))
def test_usb_loss_is_exactly_the_bytes_that_never_reach_the_host(fw, writes):
    """Whatever the host does, after it has read again: usb_lost = bytes offered - bytes the host received, and
    usb_fail counts the failed writes. (Counting only the failed writes misses the packet the core zeroes.)"""
    ffi, lib = fw
    p = ffi.new("mc_primary_t *")
    lib.mc_primary_init(p, 0)
    bank = CoreBank()
    offered = failed = 0
    for n, reading in writes:
        w = bank.write(n, reading)
        offered += n
        failed += w != n
        lib.mc_primary_usb_write(p, n, w == n)
    bank.host_reads()  # the host reads what is still armed
    # the last write the port took may still be pending in the library: it did arrive
    assert p.usb_lost == offered - bank.delivered
    assert p.usb_fail == failed % 256
    assert p.usb_lost >= bank.zeroed


def test_a_failed_write_after_a_taken_one_counts_both(fw):
    ffi, lib = fw
    p = ffi.new("mc_primary_t *")
    lib.mc_primary_init(p, 0)
    lib.mc_primary_usb_write(p, 40, 1)  # armed, reported sent
    lib.mc_primary_usb_write(p, 30, 0)  # the wait for the 40 timed out: both gone
    lib.mc_primary_usb_write(p, 20, 0)  # fails at once: only its own
    assert (p.usb_lost, p.usb_fail) == (90, 2)
    lib.mc_primary_usb_write(p, 10, 1)
    lib.mc_primary_usb_write(p, 10, 1)  # the first 10 left
    assert p.usb_lost == 90
