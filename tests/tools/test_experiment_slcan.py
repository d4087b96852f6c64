"""metacell_tools.experiment's buffered slcan reader reads what python-can's own reads, on the same byte stream."""

from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.bus.serve import open_pty
from metacell_tools.experiment.fastslcan import BufferedSlcanBus


def _read_all(bus_cls, master, path, payload, chunks):
    import os

    bus = bus_cls(channel=f"{path}@115200", sleep_after_open=0)
    try:
        while True:  # drop what the bus sent on open (C, S, O)
            try:
                if not os.read(master, 4096):
                    break
            except BlockingIOError:
                break
        for k in range(0, len(payload), chunks):  # arrives in pieces, lines split anywhere
            os.write(master, payload[k : k + chunks])
        out = []
        while True:
            try:
                m = bus.recv(timeout=0.1)
            except ValueError as e:  # python-can's parse error, counted by the runner
                out.append(("ValueError", str(e)[:20]))
                continue
            if m is None:
                return out
            out.append((m.arbitration_id, m.is_extended_id, m.is_remote_frame, m.dlc, bytes(m.data)))
    finally:
        bus.shutdown()


@settings(max_examples=15, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 0x7FF), st.binary(max_size=8)), min_size=1, max_size=30), st.integers(1, 40))
def test_buffered_slcan_reads_what_python_can_reads(frames, chunks):
    import os

    from can.interfaces.slcan import slcanBus

    lines = b"".join(b"t%03X%d%s\r" % (i, len(d), d.hex().upper().encode()) for i, d in frames)
    lines += b"\a" + b"T1234567821ABCD\r" + b"r1230\r" + b"z\r"  # error BEL, extended, remote, unknown
    master, slave, path = open_pty()
    try:
        ref = _read_all(slcanBus, master, path, lines, chunks)
        got = _read_all(BufferedSlcanBus, master, path, lines, chunks)
    finally:
        os.close(master)
        os.close(slave)
    assert got == ref and len([r for r in ref if r[0] != "ValueError"]) == len(frames) + 2
