"""Cell register handler: writes validated (CRC-8, register, length, range), applied at a tick; reads consistent."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from metacell_tools.rigtools import proto
from tests.firmware.vectors import regs as rv

D = proto.D
J = rv.J
ADDR = rv.ADDR


class Cell:
    """One compiled cell with its register handler, decoders at fixed positions."""

    def __init__(self, fw):
        self.ffi, self.lib = ffi, lib = fw
        self.c = ffi.new("mc_cell_t *")
        lib.mc_cell_init(self.c)
        self.r = ffi.new("mc_regs_t *")
        assert lib.mc_regs_init(self.r, self.c, ADDR, rv.BUILD, ffi.NULL) == lib.MC_OK
        self.a = ffi.new("mc_quad_snap_t *")
        self.b = ffi.new("mc_quad_snap_t *")
        self.buf = ffi.new("uint8_t[64]")

    def write(self, data: bytes):
        self.lib.mc_regs_on_receive(self.r, data, len(data))

    def cmd(self, reg, seq, **values):
        self.write(proto.i2c_write_frame(J, reg, seq, proto.pack_payload(reg, **values)))

    def tick(self, pos_a=0, pos_b=0, errs=(0, 0)):
        self.a.pos, self.b.pos = pos_a, pos_b
        self.a.errors, self.b.errors = errs
        return self.lib.mc_regs_tick(self.r, self.c, self.a, self.b)

    def read(self, cap=64):
        n = self.lib.mc_regs_on_request(self.r, self.buf, cap)
        return bytes(self.ffi.buffer(self.buf, n))

    def snapshot(self):
        raw = self.read()
        assert len(raw) == self.lib.MC_BLK_SNAPSHOT_LEN
        assert proto.crc8(raw[:-1]) == raw[-1]
        return proto.decode_block("SNAPSHOT", raw)

    def config(self):
        """Everything a write may change, as bytes (the tick-evolving state excluded)."""
        c, ffi = self.c, self.ffi
        return (
            bytes(ffi.buffer(ffi.addressof(c, "law"))),
            bytes(ffi.buffer(ffi.addressof(c, "drive"))),
            tuple(c.zero),
            c.enabled,
            c.bemf_comp,
            c.pert_torque,
            c.pert_ticks,
            c.pert_chain,
            c.faults,
            bytes(ffi.buffer(self.r.params[self.r.params_idx])),
        )


@pytest.fixture
def cell(fw):
    return Cell(fw)


def test_write_applies_only_at_the_tick_boundary(cell, fw):
    ffi, lib = fw
    before = cell.config()
    cell.cmd("SIGMA", 7, value=48000)
    assert cell.config() == before  # received, not applied
    assert cell.snapshot()["cmd_seq"] == 0
    cell.tick()
    law = ffi.new("mc_reaction_t *")
    phys = ffi.new("mc_reaction_phys_t *")
    lib.mc_cell_default_params(phys)
    phys.sigma_unm = 48000
    assert lib.mc_reaction_from_phys(law, phys) == lib.MC_OK
    assert bytes(ffi.buffer(law)) == bytes(ffi.buffer(ffi.addressof(cell.c, "law")))
    s = cell.snapshot()
    assert (s["cmd_seq"], s["cmd_result"], s["rejected"]) == (7, D.RESULTS["OK"], 0)


def test_params_block_reports_parameters_in_force(cell):
    cell.cmd("K_AB", 1, value=15000)
    cell.tick()
    cell.write(proto.i2c_write_frame(J, "POINTER", 0, bytes([D.BLOCKS["PARAMS"]["id"]])))
    raw = cell.read()
    assert proto.crc8(raw[:-1]) == raw[-1]
    p = proto.decode_block("PARAMS", raw)
    assert (p["tag"], p["addr"], p["k_ab"], p["sigma"], p["k1"], p["k2"], p["astar"]) == (
        0x12,
        ADDR,
        15000,
        72000,
        60000,
        -60000,
        1178097,
    )
    assert p["pwm_limit"] == cell.c.drive.duty_limit
    assert cell.read()[0] == 0x10  # the pointer went back to the snapshot


def test_ident_block(cell, fw):
    _, lib = fw
    cell.write(proto.i2c_write_frame(J, "POINTER", 0, bytes([D.BLOCKS["IDENT"]["id"]])))
    raw = cell.read()
    assert proto.crc8(raw[:-1]) == raw[-1]
    i = proto.decode_block("IDENT", raw)
    assert (i["tag"], i["addr"], i["fw_version"], i["build"], i["map_id"]) == (
        0x11,
        ADDR,
        lib.MC_FW_VERSION,
        rv.BUILD,
        lib.MC_PROTO_MAP_ID,
    )


def test_snapshot_is_one_tick(cell):
    cell.cmd("ENABLE", 3, on=1)
    for k in range(5):
        cell.tick(pos_a=10 * k, pos_b=-3 * k, errs=(k, 2 * k))
    s = cell.snapshot()
    assert (s["tick"], s["alpha"], s["beta"], s["dec_err_a"], s["dec_err_b"]) == (5, 40, -12, 4, 8)
    assert s["flags"] & (1 << D.CELL_FLAGS["ENABLED"])
    assert s["alpha"] == cell.c.theta[0] and s["beta"] == cell.c.theta[1]


def test_zero_uses_the_positions_of_its_tick(cell):
    cell.tick(pos_a=100, pos_b=-50)
    cell.cmd("ZERO", 9)
    cell.tick(pos_a=120, pos_b=-40)
    assert tuple(cell.c.zero) == (120, -40)
    assert cell.snapshot()["alpha"] == 0
    cell.tick(pos_a=125, pos_b=-40)
    assert cell.snapshot()["alpha"] == 5


def test_perturb_enable_bemf_pwm_clear(cell):
    cell.cmd("PERTURB", 1, chain=1, torque=-1000, ticks=30)
    cell.tick()
    # -1000 wire LSBs of TORQUE_WIRE_UNM uN*m each, held in TU = 2^-5 uN*m
    assert (cell.c.pert_chain, cell.c.pert_torque, cell.c.pert_ticks) == (1, -1000 * D.TORQUE_WIRE_UNM * 32, 29)
    cell.cmd("BEMF", 2, on=0)
    cell.tick()
    assert cell.c.bemf_comp == 0
    cell.cmd("PWM_LIMIT", 3, ticks=100)
    cell.tick()
    assert cell.c.drive.duty_limit == 100
    cell.cmd("PWM_LIMIT", 4, ticks=cell.c.drive.pwm_top)
    cell.tick()
    assert cell.c.drive.duty_limit == cell.c.drive.duty_max  # clamped to the 5.86 V cap
    cell.c.faults = 4
    cell.cmd("CLEAR_FAULTS", 5)
    cell.tick()
    assert cell.c.faults == 0 and cell.snapshot()["rejected"] == 0


@pytest.mark.parametrize("v", rv.CASES, ids=[c["name"] for c in rv.CASES])
def test_register_vectors(fw, v):
    """The vectors the Unity suite test/test_native_regs runs: read pointer, snapshot, PARAMS block, no side effect."""
    cell = Cell(fw)
    cell.tick()
    before = cell.config()
    cell.write(v["frame"])
    cell.tick()
    if v["pointer"]:
        assert cell.read()[0] == v["read_tag"]
    s = cell.snapshot()
    assert (s["cmd_result"], s["rejected"], s["bus_err"]) == (D.RESULTS[v["result"]], v["rejected"], v["bus_err"])
    if v["result"] == "OK":
        assert s["cmd_seq"] == v["seq"]
    else:
        assert cell.config() == before
    cell.write(proto.i2c_write_frame(J, "POINTER", 0, bytes([D.BLOCKS["PARAMS"]["id"]])))
    p = proto.decode_block("PARAMS", cell.read())
    assert (p["k_ab"], p["sigma"], p["k1"], p["k2"], p["astar"]) == v["params"]


def test_empty_receive_ignored_and_mailbox_full_counted(cell):
    cell.write(b"")  # SAMD21: onReceive(0) after a read
    cell.tick()
    assert cell.snapshot()["bus_err"] == 0 and cell.snapshot()["cmd_seq"] == 0
    cell.cmd("ENABLE", 1, on=1)
    cell.cmd("ENABLE", 2, on=0)  # before the tick: dropped
    cell.tick()
    s = cell.snapshot()
    assert (s["cmd_seq"], s["bus_err"], cell.c.enabled) == (1, 1, 1)


def test_bad_pointer_counted_and_ignored(cell):
    f = bytearray(proto.i2c_write_frame(J, "POINTER", 0, b"\x01"))
    f[-1] ^= 1
    cell.write(bytes(f))
    cell.write(proto.i2c_write_frame(J, "POINTER", 0, b"\x09"))  # no such block
    assert cell.read()[0] == 0x10
    cell.tick()
    assert cell.snapshot()["bus_err"] == 2


def test_short_read_is_truncated(cell):
    assert cell.read(cap=5) == cell.read()[:5]


frames = st.one_of(
    st.binary(max_size=16),
    st.builds(
        lambda seq, blk: (lambda body: body + bytes([proto.crc8(bytes([ADDR << 1]) + body)]))(
            bytes([D.REGISTERS["POINTER"]["id"], seq, blk])
        ),
        st.integers(0, 255),
        st.integers(0, 4),
    ),
    st.builds(
        lambda reg, seq, p: (lambda body: body + bytes([proto.crc8(bytes([ADDR << 1]) + body)]))(bytes([reg, seq]) + p),
        st.sampled_from([r["id"] for r in D.REGISTERS.values()] + [0x7F]),
        st.integers(0, 255),
        st.binary(max_size=8),
    ),
)


@settings(max_examples=400, deadline=None)
@given(frames)
def test_any_write_matches_reference_and_rejections_change_nothing(fw, frame):
    cell = Cell(fw)
    cell.tick()
    before = cell.config()
    cell.write(frame)
    cell.tick()
    if frame and frame[0] == D.REGISTERS["POINTER"]["id"]:
        # applied at once, not a command: a valid one selects the block of the next read only
        valid = (
            len(frame) == 4 and proto.crc8(bytes([ADDR << 1]) + frame[:-1]) == frame[-1] and frame[2] < len(D.BLOCKS)
        )
        assert cell.read()[0] == 0x10 | (frame[2] if valid else 0)
        s = cell.snapshot()
        assert s["cmd_result"] == D.RESULTS["NONE"] and s["bus_err"] == (0 if valid else 1)
        assert cell.config() == before
        return
    s = cell.snapshot()
    if not frame:
        assert s["cmd_result"] == D.RESULTS["NONE"]
        return
    expect = rv.reference_result(frame)
    assert s["cmd_result"] == D.RESULTS[expect], (frame.hex(), expect)
    if expect != "OK":
        assert cell.config() == before
        assert s["rejected"] == 1
