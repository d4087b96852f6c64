"""Primary scheduler: bus rate vs the I2C bound, fault isolation, commands, rejections; plus the shared vectors."""

import struct

import pytest

from host_emulator.bus.i2c import I2CTiming, lattice_rate_limit
from host_emulator.bus.rig import BusOptions, make_rig
from metacell_tools.rigtools import proto
from tests.firmware.vectors import primary as pv

D = proto.D
R = D.RESULTS


def run(rig, seconds):
    rig.advance_to(rig.t_us + int(seconds * 1e6))
    return rig.frames()


def by_kind(frames):
    out = {}
    for fid, data in frames:
        name, j = proto.frame_kind(fid)
        out.setdefault(name, []).append((j, data))
    return out


def collect(rig, seconds, step=0.02):
    """Frames over `seconds`, popped often enough that the 64-frame queue never overflows."""
    frames = []
    for _ in range(round(seconds / step)):
        frames += run(rig, step)
    assert rig.p.tx_drop == 0
    return frames


@pytest.mark.parametrize("hz", [100_000, 400_000])
def test_rate_reaches_90_percent_of_bus_limit(hz):
    rig, _ = make_rig("exp5_rest", BusOptions(i2c_hz=hz))
    collect(rig, 1.0)
    c0 = rig.p.cycles
    collect(rig, 2.0)
    rate = (rig.p.cycles - c0) / 2.0
    limit = lattice_rate_limit(hz)
    # independent bound: 16 reads of 23 bytes, (1 + 9 + 9*23 + 1) bit periods plus t_BUF each
    assert limit == pytest.approx(1 / (16 * (218 / hz + {100_000: 4.7e-6, 400_000: 1.3e-6}[hz])))
    assert rate >= 0.9 * limit
    assert rate <= limit * 1.0001


def test_samples_from_every_cell_match_the_cells():
    rig, _ = make_rig("default")
    frames = collect(rig, 0.5)
    k = by_kind(frames)
    db = proto.database()
    seen = {j for j, _ in k["CELL_SAMPLE"]}
    assert seen == set(range(1, 17))
    last = {}
    for j, data in k["CELL_SAMPLE"]:
        d = db.decode_message(D.FRAMES["CELL_SAMPLE"]["base"] + j, data)
        if j in last:
            assert d["seq"] == (last[j] + 1) & 0xFF  # healthy cell: no gaps
        last[j] = d["seq"]
    # the newest sample of each cell equals the cell's angle at (or one tick before) the read
    for j in range(1, 17):
        a = struct.unpack("<h", [d for jj, d in k["CELL_SAMPLE"] if jj == j][-1][1:3])[0]
        assert abs(a - rig.solver.cells[j - 1].theta[0]) <= 2


def test_bad_cells_never_stall_the_others():
    rig, _ = make_rig("exp5_rest", BusOptions(absent=(3,), stuck=(7,), babble=(11,)))
    frames = collect(rig, 3.0)
    k = by_kind(frames)
    counts = {j: 0 for j in range(1, 17)}
    for j, _ in k["CELL_SAMPLE"]:
        counts[j] += 1
    assert counts[3] == counts[7] == counts[11] == 0
    good = [counts[j] for j in counts if j not in (3, 7, 11)]
    healthy, _ = make_rig("exp5_rest")
    collect(healthy, 3.0)
    # a stuck cell costs one timeout per back-off period (<= 64 cycles): the others lose < 10 %
    assert min(good) >= 0.9 * healthy.p.cycles
    p = rig.p.cell
    assert p[2].nack > 0 and p[2].timeout == 0
    assert p[6].timeout > 0 and p[6].skipped > 0
    assert p[10].integrity > 0
    link = {j: d for j, d in k["CELL_LINK"]}
    assert struct.unpack("<4H", link[7])[2] > 0 and struct.unpack("<4H", link[3])[0] > 0


def send(rig, j, data, dlc=None):
    """One CAN frame from the laptop through the SLCAN text layer."""
    rig.feed(b"O\r")
    dlc = len(data) if dlc is None else dlc
    line = f"t{proto.FRAMES['CMD']['base'] + j:03X}{dlc}{data.hex().upper()}\r".encode()
    return rig.feed(line)


def results(frames):
    return [(j,) + tuple(d) for j, d in by_kind(frames).get("CMD_RESULT", [])]


def test_command_reaches_cell_and_result_comes_back():
    rig, _ = make_rig("exp5_rest")
    collect(rig, 0.05)
    assert send(rig, 4, proto.cmd_data("SIGMA", 77, value=48000)) == b"z\r"
    frames = collect(rig, 0.05)
    assert (4, D.REGISTERS["SIGMA"]["id"], 77, R["OK"], 0) in results(frames)
    c = rig.solver.cells[3]
    ffi, lib = rig.ffi, rig.lib
    law = ffi.new("mc_reaction_t *")
    ph = ffi.new("mc_reaction_phys_t *")
    lib.mc_cell_default_params(ph)
    ph.sigma_unm = 48000
    lib.mc_reaction_from_phys(law, ph)
    assert c.law.g_sigma == law.g_sigma
    assert rig.solver.cells[2].law.g_sigma != law.g_sigma  # only the addressed cell


def test_out_of_range_reported_by_the_cell_and_nothing_changes():
    rig, _ = make_rig("exp5_rest")
    collect(rig, 0.05)
    before = bytes(rig.ffi.buffer(rig.ffi.addressof(rig.solver.cells[5], "law")))
    send(rig, 6, proto.cmd_data("K1", 5, value=-5))
    frames = collect(rig, 0.05)
    assert (6, D.REGISTERS["K1"]["id"], 5, R["SHAPE"], 0) in results(frames)
    assert bytes(rig.ffi.buffer(rig.ffi.addressof(rig.solver.cells[5], "law"))) == before


def test_malformed_commands_rejected_with_status():
    rig, _ = make_rig("exp5_rest")
    collect(rig, 0.05)
    send(rig, 2, bytes([0x7E, 1]))  # unknown register
    send(rig, 2, proto.cmd_data("K_AB", 2, value=1)[:4])  # wrong length
    send(rig, 2, bytes([0x10]))  # too short
    assert rig.feed(b"t7FF0\r") == b"z\r"  # unknown id
    assert rig.feed(b"t3000\r") == b"z\r"  # cell 0
    assert rig.feed(b"T00000301110\r") == b"Z\r"  # extended id
    assert rig.feed(b"t10\r") == b"\a"  # malformed line
    frames = collect(rig, 0.05)
    res = results(frames)
    assert (2, 0x7E, 1, R["REG"], 0) in res
    assert (2, 0x10, 2, R["BAD_FRAME"], 0) in res
    rej = [struct.unpack("<BIBH", d) for _, d in by_kind(frames)["PRIMARY_REJECT"]]
    assert [(r[0], r[1] & 0x1FFFFFFF) for r in rej] == [
        (R["BAD_FRAME"], 0x7FF),
        (R["NO_CELL"], 0x300),
        (R["BAD_FRAME"], 0x301),
    ]
    assert rig.link.s.errors == 1


def test_busy_and_absent_cell():
    rig, _ = make_rig("exp5_rest", BusOptions(absent=(9,)))
    collect(rig, 0.05)
    send(rig, 1, proto.cmd_data("ENABLE", 1, on=1))
    send(rig, 1, proto.cmd_data("ENABLE", 2, on=0))
    send(rig, 9, proto.cmd_data("ENABLE", 3, on=0))
    frames = collect(rig, 0.2)
    res = results(frames)
    assert (1, 0x20, 2, R["BUSY"], 0) in res
    assert (1, 0x20, 1, R["OK"], 0) in res
    assert any(r[:4] == (9, 0x20, 3, R["NACK"]) for r in res)


def test_period_sets_the_cycle_rate():
    rig, _ = make_rig("exp5_rest", BusOptions(period_us=20_000))
    collect(rig, 1.0)
    assert rig.p.cycles == pytest.approx(50, abs=1)


def test_heartbeat_once_per_second():
    rig, _ = make_rig("exp5_rest")
    frames = collect(rig, 3.1)
    hb = [struct.unpack("<IHBB", d) for _, d in by_kind(frames)["PRIMARY_STATUS"]]
    assert [h[0] for h in hb] == pytest.approx([1000, 2000, 3000], abs=2)
    limit = lattice_rate_limit()
    assert all(h[1] >= 0.9 * limit for h in hb[1:])


def test_timing_model_bits():
    t = I2CTiming(400_000)
    assert t.bits(23) == 1 + 9 + 9 * 23 + 1
    with pytest.raises(ValueError):
        I2CTiming(123)


def test_scene_perturbations_reach_the_served_cells():
    """Both perturbation routes of a scene act on the bus-served lattice (plant torque, or the cell firmware)."""
    for via in ("plant", "firmware"):
        rig, sc = make_rig("default", overrides=[f"model_options.perturb_via={via}"])
        assert sc.options.perturb_via == via
        collect(rig, 0.5)
        assert abs(rig.solver.cells[7].theta[0]) >= 10, via


class Primary:
    """The compiled primary driven by hand, under the harness rules of tests/firmware/vectors/primary.py."""

    def __init__(self, fw):
        self.ffi, self.lib = fw
        self.p = self.ffi.new("mc_primary_t *")
        self.lib.mc_primary_init(self.p, 0)
        self.t = self.ffi.new("mc_txn_t *")
        self.now = 0

    def start(self):
        while not self.lib.mc_primary_next(self.p, self.now, self.t):
            self.now += 10
        return self.t

    def finish(self, duration, status, data=b""):
        self.now += duration
        self.lib.mc_primary_complete(self.p, self.now, status, data, len(data))

    def frames(self):
        f = self.ffi.new("mc_can_frame_t *")
        out = []
        while self.lib.mc_primary_pop(self.p, f):
            out.append((f.id, bytes(f.data)[: f.dlc]))
        return out


@pytest.mark.parametrize("v", pv.POLL_CASES, ids=[c["name"] for c in pv.POLL_CASES])
def test_poll_cycle_vectors(fw, v):
    """One poll cycle of test/test_native_primary: samples of the intact reads only, one counter per failed read."""
    pr = Primary(fw)
    for i, x in enumerate(v["cells"]):
        t = pr.start()
        assert (t.kind, t.cell, t.addr, t.len) == (pv.READ, i, proto.cell_address(i + 1), pv.SNAP_LEN)
        pr.finish(x["duration"], x["status"], x["rx"])
    samples = [(f - D.FRAMES["CELL_SAMPLE"]["base"], d) for f, d in pr.frames() if 0x100 < f <= 0x110]
    want = [(j + 1, x) for j, x in enumerate(v["cells"]) if x["sample"]]
    assert [j for j, _ in samples] == [j for j, _ in want]
    for (_, d), (_, x) in zip(samples, want):
        assert (d[0],) + struct.unpack("<hh", d[1:5]) + (d[7],) == (1, x["alpha"], x["beta"], x["flags"])
    for i, x in enumerate(v["cells"]):
        c = pr.p.cell[i]
        assert (c.nack, c.integrity, c.timeout) == (x["nack"], x["integrity"], x["timeout"]), i + 1


@pytest.mark.parametrize("v", pv.BACKOFF_CASES, ids=[c["name"] for c in pv.BACKOFF_CASES])
def test_backoff_vectors(fw, v):
    """Back-off of test/test_native_primary: the cycles a timing-out cell is polled in, and nobody else affected."""
    _, lib = fw
    pr = Primary(fw)
    polls = []
    while len(polls) < len(v["polls"]):
        t = pr.start()
        good = pv.snapshot_block(t.addr)
        if t.cell + 1 != v["cell"]:
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, good)
            continue
        polls.append(pr.p.cycles)
        if len(polls) > v["n_timeouts"]:
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, good)
        elif v["late"]:
            pr.finish(pr.p.txn_timeout_us + 1, lib.MC_I2C_OK, good)
        else:
            pr.finish(pv.DURATION_US, lib.MC_I2C_TIMEOUT)
    assert polls == v["polls"]
    c = pr.p.cell[v["cell"] - 1]
    assert (c.timeout, c.skipped) == (v["n_timeouts"], v["skipped"])
    assert all(pr.p.cell[i].timeout + pr.p.cell[i].skipped == 0 for i in range(16) if i + 1 != v["cell"])


def _reported(fid):
    b = D.FRAMES
    return fid == b["PRIMARY_REJECT"]["base"] or any(
        b[k]["base"] < fid <= b[k]["base"] + 16 for k in ("CMD_RESULT", "BLOCK_DATA")
    )


@pytest.mark.parametrize("v", pv.COMMAND_CASES, ids=[c["name"] for c in pv.COMMAND_CASES])
def test_command_vectors(fw, v):
    """Commands of test/test_native_primary: the writes and block reads, and the result/reject/block frames."""
    ffi, lib = fw
    pr = Primary(fw)
    for _ in range(16):
        t = pr.start()
        pr.finish(pv.DURATION_US, lib.MC_I2C_OK, pv.snapshot_block(t.addr))
    pr.frames()
    f = ffi.new("mc_can_frame_t *")
    for fid, data in v["can"]:
        f.id, f.dlc = fid, len(data)
        for k in range(8):
            f.data[k] = data[k] if k < len(data) else 0
        lib.mc_primary_can_rx(pr.p, pr.now, f)
    seq, result, pointer, txns = [0] * 16, [0] * 16, [False] * 16, []
    for _ in range(pv.CMD_STEPS):
        t = pr.start()
        i = t.cell
        if t.kind == pv.WRITE:
            buf = bytes(t.buf)[: t.len]
            txns.append((pv.WRITE, i + 1, t.len, buf))
            pr.finish(pv.DURATION_US, v["write_status"])
            if v["write_status"] == pv.OK and buf[0] == D.REGISTERS["POINTER"]["id"]:
                pointer[i] = True
            elif v["write_status"] == pv.OK:
                seq[i], result[i] = buf[1], v["cell_result"]
        elif pointer[i]:
            pointer[i] = False
            txns.append((pv.READ, i + 1, t.len, b""))
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, v["block_rx"])
        else:
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, pv.snapshot_block(t.addr, cmd_seq=seq[i], result=result[i]))
    assert txns == v["txns"]
    assert [(fid, d) for fid, d in pr.frames() if _reported(fid)] == v["frames"]


def blocks(frames, j):
    """Reassemble BLOCK_DATA chunks of cell j: {block id: bytes}."""
    out = {}
    for jj, d in by_kind(frames).get("BLOCK_DATA", []):
        if jj == j:
            blk, k = d[0] >> 4, d[0] & 15
            out.setdefault(blk, {})[k] = d[1:]
    return {b: b"".join(parts[k] for k in sorted(parts)) for b, parts in out.items()}


def test_pointer_command_reads_blocks_back():
    rig, _ = make_rig("exp5_rest")
    collect(rig, 0.05)
    send(rig, 3, proto.cmd_data("POINTER", 9, block=D.BLOCKS["IDENT"]["id"]))
    send(rig, 5, proto.cmd_data("SIGMA", 10, value=-12345))
    frames = collect(rig, 0.05)
    send(rig, 5, proto.cmd_data("POINTER", 11, block=D.BLOCKS["PARAMS"]["id"]))
    send(rig, 5 + 1, proto.cmd_data("POINTER", 12, block=7))  # no such block
    frames += collect(rig, 0.05)
    res = results(frames)
    assert (3, 0x01, 9, R["OK"], 0) in res and (5, 0x01, 11, R["OK"], 0) in res and (6, 0x01, 12, R["RANGE"], 0) in res
    ident = proto.decode_block("IDENT", blocks(frames, 3)[1][:11])
    assert (ident["addr"], ident["fw_version"], ident["map_id"]) == (
        proto.cell_address(3),
        rig.lib.MC_FW_VERSION,
        rig.lib.MC_PROTO_MAP_ID,
    )
    params = proto.decode_block("PARAMS", blocks(frames, 5)[2][:25])
    assert (params["addr"], params["sigma"], params["k_ab"]) == (proto.cell_address(5), -12345, 20000)
    # the polls go on undisturbed: every cell keeps sampling, no integrity errors from the pointer moves
    assert all(rig.p.cell[i].integrity == 0 for i in range(16))
    assert {j for j, _ in by_kind(frames)["CELL_SAMPLE"]} == set(range(1, 17))


def test_progress_moves_with_the_schedule_and_stands_while_a_transaction_hangs(fw):
    """mc_primary_progress: +1 per completed transaction, per ended cycle and per wait for the period; nothing while a
    transaction handed out is never completed, however often the scheduler is asked."""
    ffi, lib = fw
    p = ffi.new("mc_primary_t *")
    lib.mc_primary_init(p, 0)
    assert lib.mc_primary_configure(p, 20_000, 2000, 50_000, 64) == 0
    t = ffi.new("mc_txn_t *")
    now, done = 0, 0
    for _ in range(16):  # one cycle: every cell NACKs
        assert lib.mc_primary_next(p, now, t) == 1
        lib.mc_primary_complete(p, now + 50, lib.MC_I2C_NACK_ADDR, ffi.NULL, 0)
        now += 100
        done += 1
        assert lib.mc_primary_progress(p) == done
    assert lib.mc_primary_next(p, now, t) == 0  # end of the cycle
    assert lib.mc_primary_progress(p) == done + 1
    assert lib.mc_primary_next(p, now + 10, t) == 0  # the next cycle is not due yet: waiting is progress
    assert lib.mc_primary_progress(p) == done + 2
    assert lib.mc_primary_next(p, 20_000, t) == 1  # handed out, never completed
    stuck = lib.mc_primary_progress(p)
    for k in range(50):
        assert lib.mc_primary_next(p, 20_000 + 1000 * k, t) == 0
    assert lib.mc_primary_progress(p) == stuck
