"""SLCAN parser/encoder in C against an independent Python model of the Lawicel lines and python-can's own parsing."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.firmware.vectors import slcan as sv
from tests.firmware.vectors.slcan import model


class Slcan:
    def __init__(self, fw):
        self.ffi, self.lib = fw
        self.s = self.ffi.new("mc_slcan_t *")
        self.lib.mc_slcan_init(self.s)
        self.f = self.ffi.new("mc_can_frame_t *")
        self.reply = self.ffi.new("char[8]")

    def line(self, text: str):
        """Feed text + CR byte by byte; returns (event, reply, frame or None) of the last byte."""
        ev = None
        for b in (text + "\r").encode("latin-1"):
            ev = self.lib.mc_slcan_rx(self.s, b, self.f, self.reply)
        fr = None
        if ev == self.lib.MC_SLCAN_EV_FRAME:
            fr = (self.f.id, self.f.dlc, bytes(self.f.data)[: self.f.dlc])
        return ev, self.ffi.string(self.reply).decode(), fr

    def encode(self, fid, data, ts=0):
        f = self.ffi.new("mc_can_frame_t *")
        f.id, f.dlc = fid, len(data)
        for i, b in enumerate(data):
            f.data[i] = b
        out = self.ffi.new("char[32]")
        n = self.lib.mc_slcan_encode(self.s, f, ts, out)
        return self.ffi.buffer(out, n)[:].decode()


@pytest.fixture
def sl(fw):
    s = Slcan(fw)
    return s


alphabet = st.sampled_from(sv.ALPHABET)
lines = st.one_of(
    st.text(alphabet, max_size=30),
    st.builds(
        lambda k, i, d: k + i + str(len(d)) + d.hex(),
        st.sampled_from(["t", "r"]),
        st.text(st.sampled_from("0123456789ABCDEF"), min_size=3, max_size=3),
        st.binary(max_size=8),
    ),
    st.builds(lambda i, d: "T" + f"{i:08X}" + str(len(d)) + d.hex(), st.integers(0, 0x3FFFFFFF), st.binary(max_size=8)),
)


@settings(max_examples=600, deadline=None)
@given(st.booleans(), st.booleans(), lines)
def test_parser_matches_model(fw, is_open, listen, line):
    sl = Slcan(fw)
    if is_open:
        sl.line("L" if listen else "O")
    errs = sl.s.errors
    kind, reply, frame = model(line, is_open, listen and is_open)
    ev, got_reply, got_frame = sl.line(line)
    names = {
        fw[1].MC_SLCAN_EV_NONE: "none",
        fw[1].MC_SLCAN_EV_REPLY: "reply",
        fw[1].MC_SLCAN_EV_FRAME: "frame",
        fw[1].MC_SLCAN_EV_ERROR: "error",
    }
    assert (names[ev], got_reply, got_frame) == (kind, reply, frame), repr(line)
    assert sl.s.errors == errs + (kind == "error")


def test_open_close_and_state(sl):
    assert sl.line("t1002AABB")[0] == sl.lib.MC_SLCAN_EV_ERROR  # closed: rejected
    assert sl.line("O")[1] == "\r" and sl.s.open == 1
    assert sl.line("Z1")[1] == "\r" and sl.s.timestamps == 1
    assert sl.line("S6")[1] == "\r" and sl.s.bitrate == 6
    assert sl.line("C")[1] == "\r" and sl.s.open == 0


def test_overlong_and_binary_lines_rejected(sl):
    sl.line("O")
    assert sl.line("t" + "1" * 40)[1] == "\a"
    assert sl.line("t10\x0012")[1] == "\a"
    assert sl.line("t1000")[0] == sl.lib.MC_SLCAN_EV_FRAME  # parser recovered
    assert sl.s.errors == 2


def python_can_parse(string):
    """The frame parsing of python-can's slcanBus._recv_internal (4.x), for t/T/r/R lines."""
    if string[0] == "T":
        return int(string[1:9], 16), int(string[9]), bytes.fromhex(string[10 : 10 + int(string[9]) * 2])
    if string[0] == "t":
        return int(string[1:4], 16), int(string[4]), bytes.fromhex(string[5 : 5 + int(string[4]) * 2])
    raise AssertionError(string)


@settings(max_examples=300, deadline=None)
@given(st.booleans(), st.integers(0, 0x1FFFFFFF), st.binary(max_size=8), st.booleans(), st.integers(0, 2**32 - 1))
def test_encode_roundtrip_and_python_can_compatible(fw, ext, fid, data, ts_on, ts):
    sl = Slcan(fw)
    if not ext:
        fid &= 0x7FF
    sl.s.timestamps = int(ts_on)
    text = sl.encode(fid | (0x80000000 if ext else 0), data, ts)
    assert text.endswith("\r")
    assert python_can_parse(text) == (fid, len(data), data)
    if ts_on:
        assert int(text[-5:-1], 16) == ts % 60000
    sl.s.timestamps = 0
    sl.line("O")
    body = text[:-5] if ts_on else text[:-1]
    ev, reply, frame = sl.line(body)
    assert frame == (fid | (0x80000000 if ext else 0), len(data), data)


EV = {
    "none": "MC_SLCAN_EV_NONE",
    "reply": "MC_SLCAN_EV_REPLY",
    "frame": "MC_SLCAN_EV_FRAME",
    "error": "MC_SLCAN_EV_ERROR",
}


@pytest.mark.parametrize("v", sv.LINE_CASES, ids=[c["name"] for c in sv.LINE_CASES])
def test_line_vectors(fw, v):
    """The vectors the Unity suite test/test_native_slcan runs: event, reply, frame and error count of one line."""
    sl = Slcan(fw)
    if v["state"] != "closed":
        sl.line("L" if v["state"] == "listen" else "O")
    errs = sl.s.errors
    ev, reply, frame = sl.line(v["line"])
    if frame and frame[0] & sv.RTR:
        frame = frame[:2] + (b"",)  # a remote frame carries no data
    assert (ev, reply, frame) == (getattr(fw[1], EV[v["kind"]]), v["reply"], v["frame"])
    assert sl.s.errors == errs + (v["kind"] == "error")


def test_encode_vectors(fw):
    """The encoder vectors of test/test_native_slcan (an invalid frame encodes to nothing)."""
    for v in sv.ENCODE_CASES:
        sl = Slcan(fw)
        sl.s.timestamps = int(v["timestamps"])
        assert sl.encode(v["id"], v["data"], v["ts_ms"]) == v["text"], v
