"""Primary link: sessions drop stale frames and half lines; command answers are never dropped silently (emulated bus,
compiled C)."""

import re

from host_emulator.bus.rig import make_rig
from metacell_tools.rigtools import proto

R = proto.RESULTS
RESULT_BASE = proto.FRAMES["CMD_RESULT"]["base"]
SAMPLE_BASE = proto.FRAMES["CELL_SAMPLE"]["base"]


def lines(text: bytes):
    return re.findall(rb"t([0-9A-F]{3})(\d)([0-9A-F]*)\r", text)


def cmd_line(j, reg, seq, **values):
    data = proto.cmd_data(reg, seq, **values)
    return f"t{proto.cmd_frame_id(j):03X}{len(data)}{data.hex().upper()}\r".encode()


def results(text):
    out = []
    for fid, _, hexdata in lines(text):
        fid = int(fid, 16)
        if RESULT_BASE < fid <= RESULT_BASE + 16:
            d = bytes.fromhex(hexdata.decode())
            out.append((fid - RESULT_BASE, d[1], d[2]))
    return out


def test_a_flood_of_commands_gets_one_answer_each():
    """10,000 writes in one burst: every write is answered (OK, BUSY or NO_ROOM), none vanishes."""
    rig, _ = make_rig("exp5_rest")
    rig.feed(b"O\r")
    rig.advance_to(20_000)
    rig.drain()
    burst = b"".join(cmd_line(1 + k % 16, "ENABLE", k & 0xFF, on=1) for k in range(10_000))
    text = rig.feed(burst) and b""
    text += rig.drain()
    for _ in range(50):  # owed results arrive with the next snapshots
        rig.advance_to(rig.t_us + 10_000)
        text += rig.drain()
    got = results(text)
    assert len(got) == 10_000
    codes = {c for _, _, c in got}
    assert codes <= {R["OK"], R["BUSY"], R["NO_ROOM"]} and R["OK"] in codes
    assert rig.p.ans_drop == 0


def test_no_room_answer_when_the_queue_is_full():
    """Nobody drains: data frames stop at the reserve, commands get NO_ROOM, drops are counted in 32 bits."""
    rig, _ = make_rig("exp5_rest")
    rig.feed(b"O\r")
    lib = rig.lib
    rig.advance_to(200_000)  # queue full of samples, nobody drains
    assert rig.p.tx_drop > 255  # wide counter (the heartbeat byte saturates)
    assert lib.mc_primary_qfree(rig.p) == 16 + 2  # MC_PRIMARY_QRESERVE
    for k in range(40):
        lib.mc_link_rx(
            rig.link,
            rig.t_us,
            cmd_line(3, "ENABLE", k, on=1),
            len(cmd_line(3, "ENABLE", k, on=1)),
            rig.used,
            rig.replybuf,
            len(rig.replybuf),
        )
    got = results(rig._drain())
    assert {c for _, _, c in got} == {R["BUSY"], R["NO_ROOM"]}
    assert rig.p.no_room == sum(c == R["NO_ROOM"] for _, _, c in got)
    # every command is answered, owed (accepted, result to come) or counted as dropped
    assert len(got) + rig.p.inflight + rig.p.ans_drop == 40
    assert rig.p.inflight == 1


def test_open_drops_stale_frames_and_session_drops_the_half_line():
    rig, _ = make_rig("exp5_rest")
    rig.feed(b"O\r")
    rig.advance_to(50_000)  # frames queued, not drained (a client that stopped reading)
    queued = 127 - rig.lib.mc_primary_qfree(rig.p)
    assert queued > 0
    rig.feed(b"C\rO\r")  # a new client opens: the queued frames are stale
    assert rig.p.stale_drop >= queued
    assert rig.drain() == b""
    # a client dies mid-line; the next one's first command must not be spoiled by the half line
    rig.feed(cmd_line(2, "ENABLE", 7, on=1)[:5])
    rig.session()
    assert rig.link.s.open == 0 and rig.link.s.len == 0
    rig.feed(b"O\r" + cmd_line(2, "ENABLE", 8, on=0))
    text = b""
    for _ in range(10):
        rig.advance_to(rig.t_us + 10_000)
        text += rig.drain()
    assert (2, 8, R["OK"]) in results(text)
    assert rig.link.s.errors == 0


def test_a_plant_range_stop_becomes_the_cells_runaway_fault():
    """Drive a band past its physical range: the emulated rig runs on, the two cells report the runaway fault."""
    rig, _ = make_rig("exp5_rest")
    sol, lib = rig.solver, rig.lib
    rig.advance_to(10_000)
    sol.x[4] += 6.0  # cell 5 alpha 6 rad from its neighbours: past the band stop (4.1 rad)
    rig.advance_to(200_000)  # would raise NumericalInstability without the stop
    assert rig.band_stops >= 1
    faults = [int(sol.cells[j].faults) for j in range(16)]
    assert any(f & lib.MC_FAULT_RUNAWAY_A for f in faults[3:6])
    assert all(abs(x) < 10 for x in sol.x)


def test_a_plant_range_stop_on_a_sheet_faults_the_bond_s_two_cells():
    """On a 4 x 4 sheet the plant names the stretched bond in its edge list: the cells at its two ends latch the
    runaway fault (cell 6 and a neighbour: 2, 5, 7 or 10), not the chain's (j, j + 1) read from the bond's index."""
    rig, _ = make_rig("sheet_4x4_rig")
    sol, lib = rig.solver, rig.lib
    assert rig.n == 16 and rig.solver.h.plant.nbond == 24
    rig.advance_to(10_000)
    sol.x[5] += 6.0  # cell 6 (row 2, col 2) alpha 6 rad from its four neighbours: past the band stop
    rig.advance_to(200_000)
    assert rig.band_stops >= 1
    hit = {j + 1 for j in range(16) if int(sol.cells[j].faults) & lib.MC_FAULT_RUNAWAY_A}
    assert 6 in hit and hit - {6} and hit <= {2, 5, 6, 7, 10}, hit
    assert all(abs(x) < 10 for x in sol.x)
