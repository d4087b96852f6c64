"""The generated C header and DBC agree with protocol/definition.py; CRC-8 matches an independent bitwise reference."""

import struct
import subprocess
import sys
import types
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import codec, generate
from protocol import definition as D
from protocol import wire as proto

ROOT = Path(__file__).resolve().parents[2]


def test_generated_files_are_current():
    """Fails while a generated file differs from what `python -m protocol.generate` writes (stale or hand-edited)."""
    r = subprocess.run([sys.executable, "-m", "protocol.generate", "--check"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr


def test_check_notices_a_stale_file(tmp_path, monkeypatch):
    """The staleness check can fail: a generated file differing by one byte is reported."""
    stale = tmp_path / "mc_units.h"
    stale.write_text(generate.render_units_header(D).replace(str(D.TORQUE_WIRE_UNM), "9", 1))
    monkeypatch.setattr(generate, "UNITS_HEADER", stale)
    assert generate.main(["--check"]) == 1
    stale.write_text(generate.render_units_header(D))
    assert generate.main(["--check"]) == 0


def test_c_constants_follow_definition(fw):
    _, lib = fw
    assert lib.MC_PROTO_VERSION == D.PROTO_VERSION
    assert lib.MC_ADDR_BASE == D.ADDR_BASE and lib.MC_N_CELLS == D.N_CELLS and lib.MC_MAX_CELLS == D.MAX_CELLS
    for name, b in D.BLOCKS.items():
        off = 0
        for fname, ftype, _ in b["fields"]:
            assert getattr(lib, f"MC_{name}_{fname.upper()}") == off
            off += D.TYPE_SIZES[ftype]
        assert getattr(lib, f"MC_BLK_{name}_LEN") == off
        assert getattr(lib, f"MC_BLK_{name}_TAG") == (D.PROTO_VERSION << 4) | b["id"]
    for name, r in D.REGISTERS.items():
        assert getattr(lib, f"MC_REG_{name}") == r["id"]
        assert getattr(lib, f"MC_REG_{name}_LEN") == sum(D.TYPE_SIZES[f[1]] for f in r["payload"])
    for name, code in D.RESULTS.items():
        assert getattr(lib, f"MC_RES_{name}") == code
    for name, f in D.FRAMES.items():
        assert getattr(lib, f"MC_CAN_{name}") == f["base"]


def test_definition_uses_the_flash_tool_address_mapping(fw):
    from metacell_tools.flash import addresses

    _, lib = fw
    assert (D.ADDR_BASE, D.N_CELLS) == (addresses.ADDR_BASE, addresses.CELL_COUNT)
    assert [lib.MC_ADDR_BASE + j - 1 for j in range(1, 17)] == [addresses.cell_address(j) for j in range(1, 17)]


def test_addresses_avoid_reserved_ranges_and_are_one_to_one():
    """Cells 1..16 (the rig as built) at 0x10..0x1F, a sheet's cells up to 64 at 0x10..0x4F, all clear of the reserved
    I2C addresses 0x00-0x07 and 0x78-0x7F; cell 65 and the addresses around the range belong to no cell."""
    assert (D.N_CELLS, D.MAX_CELLS) == (16, 64)
    addrs = [proto.cell_address(j) for j in range(1, D.MAX_CELLS + 1)]
    assert len(set(addrs)) == D.MAX_CELLS
    assert all(0x08 <= a <= 0x77 for a in addrs)
    assert (addrs[0], addrs[D.N_CELLS - 1], addrs[-1]) == (0x10, 0x1F, 0x4F)
    assert [proto.cell_of_address(a) for a in addrs] == list(range(1, D.MAX_CELLS + 1))
    for bad in (0, D.MAX_CELLS + 1, -1, True, 2.0):
        with pytest.raises(ValueError):
            proto.cell_address(bad)
    for bad_addr in (0x0F, 0x50, 0x78):
        with pytest.raises(ValueError):
            proto.cell_of_address(bad_addr)


def test_per_cell_can_ids_of_64_cells_never_collide():
    """Every CAN id of a 64-cell sheet (6 per-cell frames x 64, the 3 primary frames) is one 11-bit id of one frame;
    the check refuses a definition whose per-cell ranges would overlap."""
    ids = proto.per_cell_ids()
    every = [i for r in ids.values() for i in r] + [f["base"] for f in D.FRAMES.values() if not f["per_cell"]]
    assert len(every) == len(set(every)) == 6 * 64 + 3 and max(every) <= 0x7FF
    sample = D.FRAMES["CELL_SAMPLE"]["base"]
    assert [proto.frame_kind(sample + j, D.MAX_CELLS) for j in (1, 16, 17, 64)] == [
        ("CELL_SAMPLE", j) for j in (1, 16, 17, 64)
    ]
    assert proto.frame_kind(sample + 65, D.MAX_CELLS) == ("UNKNOWN", None)
    assert proto.frame_kind(sample + 17) == ("UNKNOWN", None)  # the rig as built: a bigger sheet's cell is foreign
    tight = types.SimpleNamespace(
        MAX_CELLS=D.MAX_CELLS, FRAMES=dict(D.FRAMES, CELL_LINK=dict(D.FRAMES["CELL_LINK"], base=0x230))
    )
    with pytest.raises(ValueError, match="both CELL_STATUS and CELL_LINK"):
        proto.per_cell_ids(tight)
    wide = types.SimpleNamespace(
        MAX_CELLS=D.MAX_CELLS, FRAMES=dict(D.FRAMES, BLOCK_DATA=dict(D.FRAMES["BLOCK_DATA"], base=0x7E0))
    )
    with pytest.raises(ValueError, match="not an 11-bit id"):
        proto.per_cell_ids(wide)


def test_crc8_check_value(fw):
    _, lib = fw
    # published check value of CRC-8/SMBUS (poly 0x07, init 0) over "123456789"
    assert proto.crc8(b"123456789") == 0xF4
    assert lib.mc_crc8(b"123456789", 9) == 0xF4


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=64), st.integers(0, 255))
def test_crc8_matches_bitwise_reference(fw, data, init):
    _, lib = fw
    assert lib.mc_crc8_update(init, data, len(data)) == proto.crc8(data, init)


def test_dbc_has_every_frame_with_the_defined_layout():
    db = proto.database()
    for name, f in D.FRAMES.items():
        cells = range(1, D.MAX_CELLS + 1) if f["per_cell"] else [None]
        for j in cells:
            m = db.get_message_by_frame_id(f["base"] + (j or 0))
            assert m.name == (f"{name}_{j:02d}" if j else name)
            if f.get("multiplexed"):
                continue
            off = 0
            for sname, stype, scale, offset, _, _ in f["signals"]:
                s = m.get_signal_by_name(sname)
                assert (s.start, s.length, s.is_signed) == (8 * off, 8 * D.TYPE_SIZES[stype], stype[0] == "i")
                assert (s.scale, s.offset) == generate.dbc_physical(D).get((name, sname), (scale, offset, ""))[:2]
                off += D.TYPE_SIZES[stype]


@settings(max_examples=100, deadline=None)
@given(
    st.integers(1, 16),
    st.integers(0, 255),
    st.integers(-32768, 32767),
    st.integers(-32768, 32767),
    st.integers(0, 65535),
    st.integers(0, 255),
)
def test_dbc_decodes_sample_frames(j, seq, a, b, t, flags):
    data = struct.pack("<BhhHB", seq, a, b, t, flags)
    raw = proto.database().decode_message(
        D.FRAMES["CELL_SAMPLE"]["base"] + j, data, scaling=False, decode_choices=False
    )
    assert (raw["seq"], raw["alpha"], raw["beta"], raw["flags"]) == (seq, a, b, flags)
    d = proto.database().decode_message(D.FRAMES["CELL_SAMPLE"]["base"] + j, data)  # physical units
    assert d["alpha"] == pytest.approx(a * codec.RAD_PER_COUNT) and d["beta"] == pytest.approx(b * codec.RAD_PER_COUNT)
    if flags in D.DBC_CHOICES[("CELL_SAMPLE", "flags")]:
        assert str(d["flags"]) == D.DBC_CHOICES[("CELL_SAMPLE", "flags")][flags]
    assert d["t128"] == pytest.approx(t * 128e-6)


@settings(max_examples=100, deadline=None)
@given(
    st.integers(1, 16), st.integers(0, 255), st.sampled_from([0, 1]), st.integers(-32768, 32767), st.integers(0, 65535)
)
def test_dbc_decodes_command_frames(j, seq, chain, torque, ticks):
    data = proto.cmd_data("PERTURB", seq, chain=chain, torque=torque, ticks=ticks)
    d = proto.database().decode_message(proto.cmd_frame_id(j), data + bytes(8 - len(data)))
    assert str(d["reg"]) == "PERTURB" and d["seq"] == seq
    assert str(d["PERTURB_chain"]) == ("ALPHA", "BETA")[chain] and d["PERTURB_ticks"] == ticks
    assert d["PERTURB_torque"] == pytest.approx(D.TORQUE_WIRE_UNM * 1e-6 * torque)  # N*m
    raw = proto.database().decode_message(
        proto.cmd_frame_id(j), data + bytes(8 - len(data)), scaling=False, decode_choices=False
    )
    assert (raw["reg"], raw["PERTURB_chain"], raw["PERTURB_torque"]) == (D.REGISTERS["PERTURB"]["id"], chain, torque)
