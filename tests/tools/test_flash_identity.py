"""Flashing tool, the identity: address map, identity wire format (against the C formatter), the `ID?` query over
serial, `identify`."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from metacell_tools.flash import __main__ as cli
from metacell_tools.flash.addresses import CELL_ADDRESSES, RESERVED, address_cell, cell_address
from metacell_tools.flash.identity import (
    REQUEST,
    SAFE_BAUD,
    Identity,
    IdentityError,
    QueryResult,
    expected_fw_version,
    open_serial,
    parse_identity,
    query_identity,
)
from tests.tools.flash_fakes import fake_ports

ROOT = Path(__file__).resolve().parents[2]
IDENT_H = ROOT / "src" / "common" / "mc_ident.h"
IDENT_C = ROOT / "src" / "common" / "mc_ident.c"


# ---- the C side of the identity format, built on the host -----------------------


@pytest.fixture(scope="module")
def ident_c(tmp_path_factory):
    """src/common/mc_ident.c compiled with -std=c99 -Wall -Wextra -Werror via cffi."""
    import cffi

    from host_emulator import firmware

    ffi = cffi.FFI()
    ffi.cdef(firmware.cdef_source([IDENT_H]))
    ffi.set_source(
        "_mc_ident_test",
        f'#include "{IDENT_H}"',
        sources=[str(IDENT_C)],
        extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"],
    )
    so = ffi.compile(tmpdir=str(tmp_path_factory.mktemp("ident")), verbose=False)
    spec = importlib.util.spec_from_file_location("_mc_ident_test", so)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib


def c_format(ident_c, role, cell, addr, fw):
    ffi, lib = ident_c
    buf = ffi.new("char[]", lib.MC_IDENT_LINE_MAX)
    n = lib.mc_ident_format(buf, lib.MC_IDENT_LINE_MAX, role, cell, addr, fw)
    return None if n < 0 else ffi.string(buf, n).decode("ascii")


def test_address_map_is_one_to_one_and_unreserved():
    assert sorted(CELL_ADDRESSES) == list(range(1, 17))
    addrs = list(CELL_ADDRESSES.values())
    assert len(set(addrs)) == 16 and not set(addrs) & RESERVED
    assert all(0x08 <= a <= 0x77 for a in addrs)
    assert cell_address(1) == 0x10 and cell_address(16) == 0x1F
    assert all(address_cell(cell_address(j)) == j for j in range(1, 17))
    # a sheet's cells 17..64 continue the map to 0x4F, clear of the reserved 0x78..0x7F; cell 65 has no address
    assert [cell_address(j) for j in (17, 64)] == [0x20, 0x4F]
    assert all(address_cell(cell_address(j)) == j for j in range(1, 65))
    assert not {cell_address(j) for j in range(1, 65)} & RESERVED
    for bad in (0, 65, -1, True, "3", 2.0):
        with pytest.raises(ValueError):
            cell_address(bad)
    with pytest.raises(ValueError, match="belongs to no cell"):
        address_cell(0x50)


def test_prompt_example_line_parses():
    ident = parse_identity("MC role=cell addr=0x10 cell=1 fw=1.0\r\n")
    assert ident == Identity("cell", "1.0", 1, 0x10)
    assert parse_identity("MC role=primary fw=1.0") == Identity("primary", "1.0")
    assert parse_identity("MC role=cell addr=none cell=0 fw=2.3") == Identity("cell", "2.3", 0, None)


@pytest.mark.parametrize(
    "line, why",
    [
        ("MC role=cell addr=0x10 fw=1.0", "cell must be"),
        ("MC role=cell addr=0x10 cell=65 fw=1.0", "cell must be"),
        ("MC role=cell addr=0x05 cell=1 fw=1.0", "reserved"),
        ("MC role=cell addr=0x7c cell=1 fw=1.0", "reserved"),
        ("MC role=cell addr=none cell=3 fw=1.0", "inconsistent"),
        ("MC role=cell addr=0x12 cell=0 fw=1.0", "inconsistent"),
        ("MC role=cell addr=18 cell=3 fw=1.0", "addr must be"),
        ("MC role=robot fw=1.0", "role must be"),
        ("MC role=primary fw=1", "fw must be"),
        ("MC role=primary fw=01.0", "fw must be"),
        ("MC role=cell addr=0x12 cell=03 fw=1.0", "cell must be"),
        ("MC role=primary fw=1.300", "fw must be"),
        ("MC role=primary addr=0x10 fw=1.0", "primary reply carries"),
        ("MC role=primary role=cell fw=1.0", "repeated"),
        ("MC role=primary fw", "bad field"),
        ("ID?", "not an identity line"),
    ],
)
def test_malformed_identity_lines_are_refused_with_the_reason(line, why):
    with pytest.raises(IdentityError, match=why):
        parse_identity(line)


@settings(max_examples=400, deadline=None)
@given(role=st.integers(0, 3), cell=st.integers(-2, 18), addr=st.integers(-1, 0x82), fw=st.integers(0, 0xFFFF))
def test_c_formatter_and_python_parser_agree(ident_c, role, cell, addr, fw):
    line = c_format(ident_c, role, cell, addr, fw)
    valid_cell = role == 1 and 0 <= cell <= 16 and (addr == 0 if cell == 0 else 0x08 <= addr <= 0x77)
    assert (line is not None) == (valid_cell or role == 2)
    if line is None:
        return
    assert line.endswith("\r\n") and len(line) < ident_c[1].MC_IDENT_LINE_MAX
    got = parse_identity(line)
    fw_s = f"{fw >> 8}.{fw & 0xFF}"
    if role == 2:
        assert got == Identity("primary", fw_s)
    else:
        assert got == Identity("cell", fw_s, cell, addr if cell else None)


def test_c_formatter_refuses_a_short_buffer_and_leaves_it_untouched(ident_c):
    ffi, lib = ident_c
    buf = ffi.new("char[]", b"Z" * 10)
    assert lib.mc_ident_format(buf, 10, 1, 3, 0x12, 0x0100) == -1
    assert ffi.buffer(buf)[:10] == b"Z" * 10
    assert lib.mc_ident_format(ffi.NULL, 64, 2, 0, 0, 0x0100) == -1


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.sampled_from([b"I", b"D", b"?", b"\r", b"\n", b"x", b"ID?", b"ID?\r", b"IID?", b"ID?\n"]), max_size=40)
)
def test_c_request_matcher_fires_exactly_on_lines_equal_to_ID(ident_c, chunks):
    ffi, lib = ident_c
    stream = b"".join(chunks)
    rx = ffi.new("mc_ident_rx_t *")
    lib.mc_ident_rx_init(rx)
    fired = [i for i, byte in enumerate(stream) if lib.mc_ident_rx_feed(rx, byte)]
    # reference: positions of line terminators whose preceding line is exactly b"ID?"
    expect, start = [], 0
    for i, byte in enumerate(stream):
        if byte in b"\r\n":
            if stream[start:i] == b"ID?":
                expect.append(i)
            start = i + 1
    assert fired == expect


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_parser_never_fails_other_than_with_identity_error(text):
    try:
        got = parse_identity("MC " + text)
    except IdentityError:
        return
    assert got.role in ("cell", "primary")


def test_expected_fw_version_comes_from_the_library_header(tmp_path):
    text = (ROOT / "lib/metacell/src/mc_cell.h").read_text()
    v = int(re.search(r"#define\s+MC_FW_VERSION\s+(\S+)", text).group(1), 0)
    assert expected_fw_version() == f"{v >> 8}.{v & 0xFF}"
    h = tmp_path / "x.h"
    h.write_text("#define MC_FW_VERSION 0x0203\n")
    assert expected_fw_version(h) == "2.3"
    h.write_text("nothing\n")
    with pytest.raises(RuntimeError):
        expected_fw_version(h)


# ---- the serial side of the identity query ----------------------------------------------


class FakeSerial:
    def __init__(self, replies):
        self.replies, self.written, self.closed = list(replies), [], False

    def write(self, data):
        self.written.append(data)

    def readline(self):
        return self.replies.pop(0) if self.replies else b""

    def close(self):
        self.closed = True


def test_query_skips_noise_collects_errors_and_closes():
    fake = FakeSerial([b"", b"t1230\r", b"MC error=tick\r\n", b"MC role=cell addr=0x13 ", b"cell=4 fw=1.0\r\n"])
    t = iter(range(1000))
    q = query_identity("/dev/x", opener=lambda d: fake, clock=lambda: next(t) * 0.01)
    assert q.identity == Identity("cell", "1.0", 4, 0x13)
    assert q.errors == ["tick"] and "t1230" in q.raw
    assert fake.written[0] == REQUEST == b"ID?\r\n" and fake.closed


def test_query_times_out_resending_the_request():
    fake = FakeSerial([])
    t = iter(range(10000))
    q = query_identity("/dev/x", opener=lambda d: fake, timeout=2.0, retry_every=0.5, clock=lambda: next(t) * 0.1)
    assert q.identity is None and fake.closed
    assert 3 <= len(fake.written) <= 5


def test_serial_is_never_opened_at_1200_baud(monkeypatch):
    seen = {}
    monkeypatch.setattr("serial.Serial", lambda dev, **kw: seen.update(kw, dev=dev))
    open_serial("/dev/ttyACM0")
    assert seen["baudrate"] == SAFE_BAUD != 1200


def test_identify_flags_two_boards_claiming_one_address(tmp_path, capsys):
    ports = fake_ports(3)
    answers = {
        "/dev/ttyACM0": Identity("cell", "1.0", 3, 0x12),
        "/dev/ttyACM1": Identity("cell", "1.0", 3, 0x12),
        "/dev/ttyACM2": Identity("primary", "1.0"),
    }
    args = SimpleNamespace(inventory=str(tmp_path / "none.json"))
    rc = cli.cmd_identify(
        args, lambda: ports, lambda m, err=False: print(m), query=lambda d: QueryResult(answers[d], [], [])
    )
    out = capsys.readouterr().out
    assert rc == cli.EXIT_FAILED
    assert "two boards claim address 0x12: /dev/ttyACM0 (serial SN00), /dev/ttyACM1 (serial SN01)" in out
    answers["/dev/ttyACM1"] = Identity("cell", "1.0", 4, 0x13)
    assert (
        cli.cmd_identify(
            args, lambda: ports, lambda m, err=False: None, query=lambda d: QueryResult(answers[d], [], [])
        )
        == cli.EXIT_OK
    )
