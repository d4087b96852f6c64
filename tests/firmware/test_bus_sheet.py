"""A sheet's data path: the compiled primary polls n cells (up to 64) in order, answers commands to cells beyond n with
NO_CELL, and the hil bus model reaches the I2C bound at 16, 32 and 64 cells."""

import pytest

from host_emulator.bus.i2c import I2CTiming, lattice_rate_limit
from host_emulator.bus.rig import BusOptions, make_rig
from metacell_tools.rigtools import proto
from tests.firmware.test_bus_primary import Primary
from tests.firmware.vectors import primary as pv

D = proto.D


def test_a_fresh_primary_polls_the_rig_as_built(fw):
    """After init: 16 cells (the rig as built), their order and the reserve as before sheets."""
    pr = Primary(fw)
    assert pr.p.n_cells == D.N_CELLS == 16
    addrs = []
    for _ in range(2 * D.N_CELLS):
        t = pr.start()
        addrs.append(t.addr)
        pr.finish(pv.DURATION_US, fw[1].MC_I2C_OK, pv.snapshot_block(t.addr))
    assert addrs == 2 * [0x10 + i for i in range(16)]


@pytest.mark.parametrize("n", [4, 32, 64])
def test_n_cells_polled_in_order_and_commands_beyond_n_refused(fw, n):
    ffi, lib = fw
    pr = Primary(fw)
    assert lib.mc_primary_set_cells(pr.p, n) == 0 and pr.p.n_cells == n
    frames = []
    for cycle in range(2):
        for i in range(n):
            t = pr.start()
            assert (t.kind, t.cell, t.addr, t.len) == (pv.READ, i, proto.cell_address(i + 1), pv.SNAP_LEN), cycle
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, pv.snapshot_block(t.addr))
            frames += pr.frames()  # popped after each transaction, as the glue sends them out
    samples = [f - D.FRAMES["CELL_SAMPLE"]["base"] for f, _ in frames if proto.frame_kind(f, 64)[0] == "CELL_SAMPLE"]
    assert samples == 2 * list(range(1, n + 1)) and pr.p.tx_drop == 0
    assert pr.start().addr == 0x10 and pr.p.cycles == 2  # the third cycle starts at cell 1 again
    f = ffi.new("mc_can_frame_t *")
    for j, want in ((n, None), (n + 1, D.RESULTS["NO_CELL"])):
        f.id, f.dlc = D.FRAMES["CMD"]["base"] + j, 3
        f.data[0:3] = [D.REGISTERS["ENABLE"]["id"], 7, 1]
        lib.mc_primary_can_rx(pr.p, pr.now, f)
        out = pr.frames()
        rejects = [d for fid, d in out if fid == D.FRAMES["PRIMARY_REJECT"]["base"]]
        if want is None:  # accepted: it goes on the bus, nothing answered yet
            assert rejects == [] and pr.p.cell[j - 1].cmd_state == lib.MC_CMD_PENDING
        else:  # PRIMARY_REJECT: reason NO_CELL, the rejected id
            assert [(d[0], int.from_bytes(d[1:5], "little")) for d in rejects] == [(want, f.id)]


def test_every_cell_of_a_64_cell_sheet_gets_its_status_in_rotation(fw):
    _, lib = fw
    pr = Primary(fw)
    assert lib.mc_primary_set_cells(pr.p, 64) == 0
    status = set()
    for _ in range(pr.p.status_every):
        for _ in range(64):
            t = pr.start()
            pr.finish(pv.DURATION_US, lib.MC_I2C_OK, pv.snapshot_block(t.addr))
            status |= {proto.frame_kind(f, 64)[1] for f, _ in pr.frames() if proto.frame_kind(f, 64)[0] == "CELL_LINK"}
    pr.start()  # the 64th cycle ends (and sends its status) when the next one starts
    status |= {proto.frame_kind(f, 64)[1] for f, _ in pr.frames() if proto.frame_kind(f, 64)[0] == "CELL_LINK"}
    assert status == set(range(1, 65))


def test_cell_counts_the_primary_refuses(fw):
    _, lib = fw
    pr = Primary(fw)
    for bad in (0, D.MAX_CELLS + 1, 255):
        assert lib.mc_primary_set_cells(pr.p, bad) == -1 and pr.p.n_cells == 16
    assert lib.mc_primary_configure(pr.p, 0, 2000, 50000, 16) == 0
    assert lib.mc_primary_set_cells(pr.p, 17) == -1  # status_every 16 would never reach cell 17's status
    assert lib.mc_primary_configure(pr.p, 0, 2000, 50000, 64) == 0
    assert lib.mc_primary_set_cells(pr.p, 64) == 0
    assert lib.mc_primary_configure(pr.p, 0, 2000, 50000, 63) == -1 and pr.p.status_every == 64
    pr.start()  # the schedule has started: the count stays
    assert lib.mc_primary_set_cells(pr.p, 32) == -1 and pr.p.n_cells == 64


@pytest.mark.parametrize("n", [16, 32, 64])
def test_hil_bus_reaches_the_i2c_bound_for_n_cells(n):
    """Cycles per simulated second of the compiled primary on the emulated 400 kHz bus: within 10 % of the bound
    1 / (n x 546.3 us) (an independent count of the read's bit periods), every cell sampled once per cycle."""
    rig, sc = make_rig("exp5_rest", BusOptions(), overrides=[f"cells={n}"])
    assert sc.cells == n and rig.p.n_cells == max(n, 16)
    step = 2_000  # popped every 2 ms: a few transactions, as the firmware's loop sends frames out after each one
    rig.advance_to(10 * step)
    rig.frames()  # the first cycles' burst (each cell's first status frame) is left behind here
    c0, drops = rig.p.cycles, rig.p.tx_drop
    per_cell = dict.fromkeys(range(1, n + 1), 0)
    for _ in range(250):  # 0.5 s
        rig.advance_to(rig.t_us + step)
        for fid, _ in rig.frames():
            kind, j = proto.frame_kind(fid, n)
            if kind == "CELL_SAMPLE":
                per_cell[j] += 1
    rate = (rig.p.cycles - c0) / 0.5
    bound = 1 / (n * ((1 + 9 + 9 * 23 + 1) / 400_000 + 1.3e-6))
    assert lattice_rate_limit(400_000, cells=n) == pytest.approx(bound)
    assert 0.9 * bound <= rate <= bound * 1.0001
    assert min(per_cell.values()) >= 0.5 * 0.9 * bound - 1 and rig.p.tx_drop == drops
    assert I2CTiming(400_000).transaction_s(23) == pytest.approx(546.3e-6)
