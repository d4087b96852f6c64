"""The image tier's laptop speaks SLCAN as python-can's slcan interface does: frame text, parsing, open and close."""

from __future__ import annotations

import can
import pytest
from can.interfaces.slcan import slcanBus
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.image.laptop import CLOSE_SEQUENCE, OPEN_SEQUENCE, decode_line, encode_frame


class MemoryPort:
    """An in-memory stand-in for the pyserial port slcanBus opens: records what it writes, serves `rx` to its reads."""

    def __init__(self, *args, **kwargs) -> None:
        self.written = bytearray()
        self.rx = bytearray()
        self.write_timeout = None
        self.closed = False

    def write(self, data: bytes) -> int:
        assert not self.closed
        self.written += data
        return len(data)

    def flush(self) -> None:
        pass

    @property
    def in_waiting(self) -> int:
        return len(self.rx)

    def read(self, n: int = 1) -> bytes:
        out = bytes(self.rx[:n])
        del self.rx[:n]
        return out

    def reset_input_buffer(self) -> None:
        self.rx.clear()

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def memory_bus(monkeypatch):
    """(slcanBus opened with the rig's bit rate on a MemoryPort, the port)."""
    port = MemoryPort()
    monkeypatch.setattr("can.interfaces.slcan.serial.serial_for_url", lambda *a, **k: port)
    bus = slcanBus(channel="memory", bitrate=500000, sleep_after_open=0)
    yield bus, port
    if not port.closed:
        bus.shutdown()


@pytest.fixture(scope="module")
def loop_bus():
    """slcanBus on pyserial's loopback port: what it sends comes back to its own reader."""
    bus = slcanBus(channel="loop://", sleep_after_open=0)
    yield bus
    bus.shutdown()


def drain(bus: slcanBus) -> bytes:
    """Everything waiting on the loopback port. (One read of in_waiting bytes is not enough: the loop port's read
    gives up after its 1 ms timeout, however many bytes wait, so a busy machine would cut it short.)"""
    port, out = bus.serialPortOrig, bytearray()
    while port.in_waiting:
        out += port.read(port.in_waiting)
    return bytes(out)


def test_the_open_sequence_is_what_python_can_writes_at_the_rigs_bit_rate(memory_bus):
    bus, port = memory_bus
    assert bytes(port.written) == OPEN_SEQUENCE


def test_the_close_sequence_is_what_python_can_writes_on_shutdown(memory_bus):
    bus, port = memory_bus
    port.written.clear()
    bus.shutdown()
    assert port.closed and bytes(port.written) == CLOSE_SEQUENCE


std_id = st.integers(0, 0x7FF)
ext_id = st.integers(0, 0x1FFF_FFFF)
payload = st.binary(max_size=8)


@settings(max_examples=300)
@given(std_id, payload)
def test_encode_frame_is_python_cans_text(loop_bus, ident, data):
    drain(loop_bus)
    loop_bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
    assert encode_frame(ident, data) == drain(loop_bus)


@settings(max_examples=300)
@given(st.one_of(st.tuples(std_id, st.just(False)), st.tuples(ext_id, st.just(True))), payload)
def test_decode_line_reads_python_cans_frames_as_python_can_does(loop_bus, id_ext, data):
    ident, extended = id_ext
    drain(loop_bus)
    loop_bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=extended))
    line = drain(loop_bus)
    assert line.endswith(b"\r")
    loop_bus.serialPortOrig.write(line)  # back through python-can's own reader
    msg = loop_bus.recv(timeout=1.0)
    assert msg is not None and msg.is_extended_id == extended
    assert decode_line(line[:-1]) == (msg.arbitration_id, bytes(msg.data)) == (ident, data)


@given(std_id, payload, st.integers(0, 0xFFFF))
def test_a_lawicel_timestamp_after_the_data_is_ignored_as_python_can_ignores_it(loop_bus, ident, data, ts):
    line = encode_frame(ident, data)[:-1] + f"{ts:04X}".encode()
    drain(loop_bus)
    loop_bus.serialPortOrig.write(line + b"\r")
    msg = loop_bus.recv(timeout=1.0)
    assert msg is not None
    assert decode_line(line) == (msg.arbitration_id, bytes(msg.data)) == (ident, data)


def python_can_parse(bus: slcanBus, line: bytes) -> tuple[int, bytes] | None:
    """What python-can's slcan reader makes of one line (None: no data frame, or it raised)."""
    drain(bus)
    bus.serialPortOrig.write(line + b"\r")
    try:
        msg = bus.recv(timeout=0)
    except (can.CanError, ValueError, IndexError):  # its parser raises on some malformed lines
        return None
    finally:
        drain(bus)
    return None if msg is None or msg.is_remote_frame else (msg.arbitration_id, bytes(msg.data))


HEXISH = b"0123456789abcdefABCDEFgG tTrR_+-\x07\r"


@st.composite
def damaged_lines(draw):
    """A frame line, then up to three edits: a byte replaced, inserted or deleted, or the line cut."""
    ident = draw(st.one_of(std_id, ext_id))
    data = draw(payload)
    line = bytearray(encode_frame(ident, data)[:-1] if ident <= 0x7FF else f"T{ident:08X}{len(data)}".encode())
    if ident > 0x7FF:
        line += data.hex().upper().encode()
    for _ in range(draw(st.integers(0, 3))):
        op = draw(st.sampled_from(["replace", "insert", "delete", "cut"]))
        if not line:
            break
        i = draw(st.integers(0, len(line) - 1))
        c = draw(st.sampled_from(list(HEXISH)))
        if op == "replace":
            line[i] = c
        elif op == "insert":
            line.insert(i, c)
        elif op == "delete":
            del line[i]
        else:
            del line[i:]
    return bytes(line)


@settings(max_examples=500)
@given(st.one_of(st.binary(max_size=40), damaged_lines()))
def test_decode_line_never_raises_and_any_frame_it_returns_is_python_cans(loop_bus, line):
    got = decode_line(line)
    if got is None:
        return
    ident, data = got
    assert len(data) <= 8 and 0 <= ident <= 0x1FFF_FFFF
    assert python_can_parse(loop_bus, line) == got


@pytest.mark.parametrize(
    "line",
    [
        b"",
        b"\r",
        b"z",  # the reply to a sent frame
        b"\x07",  # an error reply
        b"V1013",  # a version reply
        b"t12",  # cut in the id
        b"t123",  # no DLC
        b"t1232AB",  # DLC 2, one byte
        b"t1232ABCDE",  # DLC 2, one byte and a half
        b"t1239" + b"00" * 9,  # DLC 9
        b"t800",  # an 11-bit id beyond 0x7FF
        b"t8000",
        b"T200000000",  # a 29-bit id beyond 0x1FFFFFFF
        b"t 120",  # what int(..., 16) would forgive: spaces, signs, underscores
        b"t+120",
        b"t1_20",
        b"t12g0",
        b"t1231 AB",
        b"t1230\r",  # the CR belongs to the framing, not the line
        b"r1230",  # remote frames carry no data for the laptop
        b"R000001230",
        b"t1232\xab\xcd",
    ],
)
def test_decode_line_rejects_malformed_lines(line):
    assert decode_line(line) is None


@pytest.mark.parametrize("ident,data", [(-1, b""), (0x800, b""), (0x123, bytes(9))])
def test_encode_frame_refuses_what_is_not_a_standard_data_frame(ident, data):
    with pytest.raises(ValueError, match="not a standard CAN data frame"):
        encode_frame(ident, data)
