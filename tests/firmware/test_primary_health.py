"""PRIMARY_HEALTH: the compiled primary sends what the glue reports (reset cause, USB bytes lost, bus recoveries), the
shipped DBC decodes it, and the logger counts and shows it."""

import struct

import can

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
