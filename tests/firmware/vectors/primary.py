"""Vectors for the primary's poll scheduler: one poll cycle, timeout back-off, command forwarding; expected by a model.

The harness that runs them (pytest's and the Unity suite's, the same rules): time starts at 0, advances 10 us while
mc_primary_next() has nothing to start, and each transaction lasts DURATION_US unless a vector says otherwise.
"""

from __future__ import annotations

import struct

from metacell_tools.rigtools import proto

from . import regs

D = proto.D
BLOCK_LEN = {b["id"]: sum(D.TYPE_SIZES[f[1]] for f in b["fields"]) for b in D.BLOCKS.values()}
SNAP_LEN = BLOCK_LEN[D.BLOCKS["SNAPSHOT"]["id"]]
DURATION_US = 500
TXN_TIMEOUT_US = D.SCHEDULE["TXN_TIMEOUT_US"]
BACKOFF_MAX = D.SCHEDULE["BACKOFF_MAX"]
WRITE_RETRIES = D.SCHEDULE["WRITE_RETRIES"]
OK, NACK_ADDR, NACK_DATA, TIMEOUT, BUS_ERROR = 0, 1, 2, 3, 4  # the transport's status codes (mc_primary.h)
READ, WRITE = 0, 1
R = D.RESULTS
F = D.FRAMES


def snapshot_block(addr: int, tick=1, alpha=0, beta=0, flags=0, cmd_seq=0, result=0) -> bytes:
    body = struct.pack("<BBIhhHBBBBHHH", 0x10, addr, tick, alpha, beta, 0, flags, cmd_seq, result, 0, 0, 0, 0)
    return body + bytes([proto.crc8(body)])


def ident_block(addr: int, fw=0x0102, build=0xC0FFEE, map_id=0x1234) -> bytes:
    body = struct.pack("<BBHIH", 0x11, addr, fw, build, map_id)
    return body + bytes([proto.crc8(body)])


# ---------------------------------------------------------------- one poll cycle: every read answered as listed


def poll_reference(status: int, rx: bytes, duration: int, addr: int) -> dict:
    """What one snapshot read must do: a sample when it is intact and in time, else one counter."""
    out = {"sample": False, "nack": 0, "integrity": 0, "timeout": 0}
    if status == OK and duration > TXN_TIMEOUT_US:
        status = TIMEOUT  # completed after its deadline: the data may be stale
    if status in (NACK_ADDR, NACK_DATA):
        out["nack"] = 1
    elif status != OK:
        out["timeout"] = 1
    elif len(rx) == SNAP_LEN and rx[0] == 0x10 and rx[1] == addr and proto.crc8(rx[:-1]) == rx[-1]:
        out["sample"] = True
    else:
        out["integrity"] = 1
    return out


def _poll_case(name: str, special: dict) -> dict:
    cells = []
    for j in range(1, 17):
        a = proto.cell_address(j)
        alpha, beta, flags = 7 * j - 60, -3 * j, j & 3
        good = snapshot_block(a, tick=1000 + j, alpha=alpha, beta=beta, flags=flags)
        status, rx, dur = special.get(j, lambda a, g: (OK, g, DURATION_US))(a, good)
        cell = {"status": status, "rx": rx, "duration": dur, "alpha": alpha, "beta": beta, "flags": flags}
        cell.update(poll_reference(status, rx, dur, a))
        cells.append(cell)
    return {"name": name, "cells": cells}


POLL_CASES = [
    _poll_case("healthy", {}),
    _poll_case(
        "integrity",
        {
            2: lambda a, g: (OK, b"\xff" * SNAP_LEN, DURATION_US),  # empty transmit buffer
            3: lambda a, g: (OK, snapshot_block(a + 1), DURATION_US),  # another cell's block
            4: lambda a, g: (OK, g[:-1], DURATION_US),  # short read
            5: lambda a, g: (OK, g[:-1] + bytes([g[-1] ^ 1]), DURATION_US),  # CRC
            6: lambda a, g: (OK, bytes([0x11]) + g[1:], DURATION_US),  # wrong tag (IDENT)
        },
    ),
    _poll_case(
        "statuses",
        {
            1: lambda a, g: (NACK_ADDR, b"", 100),
            8: lambda a, g: (TIMEOUT, b"", TXN_TIMEOUT_US),
            9: lambda a, g: (BUS_ERROR, b"", 50),
            10: lambda a, g: (OK, g, TXN_TIMEOUT_US + 1),  # late
            11: lambda a, g: (NACK_DATA, b"", 100),
            16: lambda a, g: (OK, g, TXN_TIMEOUT_US),  # just in time
        },
    ),
]

# ---------------------------------------------------------------- back-off: one cell times out its first polls


def backoff_reference(n_timeouts: int, n_polls: int) -> list[int]:
    """Cycle numbers of the first n_polls polls of a cell whose first n_timeouts polls time out: skipped 1, 2, 4 ..
    BACKOFF_MAX cycles after successive timeouts, every cycle again after a good read."""
    polls, cycle, skip, length = [], 0, 0, 0
    while len(polls) < n_polls:
        if skip:
            skip -= 1
        else:
            polls.append(cycle)
            if len(polls) <= n_timeouts:
                length = min(2 * length if length else 1, BACKOFF_MAX)
                skip = length
            else:
                length = 0
        cycle += 1
    return polls


def _backoff_case(cell: int, n_timeouts: int, n_polls: int, late: bool) -> dict:
    polls = backoff_reference(n_timeouts, n_polls)
    return {
        "name": f"cell{cell}_{n_timeouts}{'_late' if late else ''}",
        "cell": cell,
        "n_timeouts": n_timeouts,
        "late": late,
        "polls": polls,
        "skipped": polls[-1] + 1 - n_polls,
    }


BACKOFF_CASES = [_backoff_case(5, 7, 20, True), _backoff_case(1, 3, 10, False), _backoff_case(16, 10, 14, False)]

# ---------------------------------------------------------------- commands: frames from the laptop after one cycle

CMD_STEPS = 48  # transactions run after the frames arrive (three cycles)


def _cmd(j: int, reg: str, seq: int, pad: bool = False, **values) -> tuple[int, bytes]:
    data = proto.cmd_data(reg, seq, **values)
    return proto.cmd_frame_id(j), data + bytes(8 - len(data)) if pad else data


def command_reference(frames, write_status: int, block_rx: bytes) -> dict:
    """Transactions (beyond the snapshot polls) and CMD_RESULT/PRIMARY_REJECT/BLOCK_DATA frames for a batch of
    frames (at most one of them accepted), the simulated cell answering writes with write_status, its block read
    with block_rx, and reporting the register verdict of the cell's handler (cell_result, by the register model)
    in its next snapshot."""
    txns, out, rejects, busy, cell_result = [], [], 0, set(), 0
    cmd_base, res_base = F["CMD"]["base"], F["CMD_RESULT"]["base"]
    reg_len = {r["id"]: sum(D.TYPE_SIZES[f[1]] for f in r["payload"]) for r in D.REGISTERS.values()}
    blk_len = BLOCK_LEN
    accepted = None
    for fid, data in frames:
        dlc, ident = len(data), fid & 0x1FFFFFFF
        if fid & 0xC0000000 or not cmd_base <= ident < res_base or not 1 <= ident - cmd_base <= 16:
            rejects += 1
            reason = "NO_CELL" if not fid & 0xC0000000 and cmd_base <= ident < res_base else "BAD_FRAME"
            out.append((F["PRIMARY_REJECT"]["base"], struct.pack("<BIBH", R[reason], fid, dlc, rejects)))
            continue
        j = ident - cmd_base
        reg, lseq = (data[0] if dlc else 0), (data[1] if dlc > 1 else 0)
        plen = reg_len.get(reg)
        res = None
        if dlc < 2:
            res = "BAD_FRAME"
        elif plen is None:
            res = "REG"
        elif dlc not in (plen + 2, 8):
            res = "BAD_FRAME"
        elif reg == D.REGISTERS["POINTER"]["id"] and data[2] not in blk_len:
            res = "RANGE"
        elif j in busy:
            res = "BUSY"
        if res:
            rejects += 1
            out.append((res_base + j, bytes([reg, lseq, R[res], 0])))
            continue
        busy.add(j)
        assert accepted is None, "the reference handles one accepted command per vector"
        accepted = (j, reg, lseq, data[2 : 2 + plen])
    if accepted:
        j, reg, lseq, payload = accepted
        name = next(k for k, r in D.REGISTERS.items() if r["id"] == reg)
        write = proto.i2c_write_frame(j, name, 1, payload)  # seq: the cell's last cmd_seq (0) + 1
        tries, done = 0, False
        while not done:
            txns.append((WRITE, j, len(write), write))
            if write_status != OK:
                result = "NACK"
            elif name == "POINTER":
                n = blk_len[payload[0]]
                txns.append((READ, j, n, b""))
                a = proto.cell_address(j)
                if len(block_rx) == n and block_rx[:2] == bytes([0x10 | payload[0], a]):
                    if proto.crc8(block_rx[:-1]) == block_rx[-1]:
                        for k in range(0, n, 7):
                            chunk = block_rx[k : k + 7]
                            out.append(
                                (F["BLOCK_DATA"]["base"] + j, bytes([payload[0] << 4 | k // 7]) + chunk.ljust(7, b"\0"))
                            )
                        out.append((res_base + j, bytes([reg, lseq, R["OK"], tries])))
                        break
                result = "CRC"
            else:
                verdict = regs.reference_result(write, proto.cell_address(j))
                cell_result = R[verdict]
                out.append((res_base + j, bytes([reg, lseq, R[verdict], tries])))
                break
            tries += 1
            if tries > WRITE_RETRIES:
                out.append((res_base + j, bytes([reg, lseq, R[result], tries])))
                done = True
    return {"txns": txns, "frames": out, "cell_result": cell_result}


def _command_case(name: str, frames, write_status: int = OK, block_rx: bytes = b"") -> dict:
    case = {"name": name, "can": frames, "write_status": write_status, "block_rx": block_rx}
    case.update(command_reference(frames, write_status, block_rx))
    return case


COMMAND_CASES = [
    _command_case("sigma_ok", [_cmd(4, "SIGMA", 77, value=48000)]),
    _command_case("sigma_padded", [_cmd(12, "SIGMA", 3, pad=True, value=-1000)]),
    _command_case("k1_shape", [_cmd(6, "K1", 5, value=-5)]),
    _command_case("nacked_write", [_cmd(9, "ENABLE", 3, on=0)], write_status=NACK_ADDR),
    _command_case(
        "pointer_ident",
        [_cmd(3, "POINTER", 9, block=D.BLOCKS["IDENT"]["id"])],
        block_rx=ident_block(proto.cell_address(3)),
    ),
    _command_case("pointer_corrupt", [_cmd(2, "POINTER", 4, block=D.BLOCKS["PARAMS"]["id"])], block_rx=b"\xff" * 25),
    _command_case(
        "malformed_and_busy",
        [
            (proto.cmd_frame_id(2), bytes([0x7E, 1])),  # unknown register
            (proto.cmd_frame_id(2), proto.cmd_data("K_AB", 2, value=1)[:4]),  # wrong length
            (proto.cmd_frame_id(2), bytes([0x10])),  # too short
            (0x7FF, b""),  # not a command id
            (F["CMD"]["base"], b""),  # cell 0
            (0x80000000 | 0x301, bytes([0x20, 1, 1])),  # extended id
            (F["CMD"]["base"] + 17, bytes([0x20, 1, 1])),  # cell 17: still a CMD id, no such cell
            _cmd(5, "POINTER", 12, block=7),  # no such block
            _cmd(1, "ENABLE", 1, on=1),
            _cmd(1, "ENABLE", 2, on=0),  # the first is still in flight
        ],
    ),
]
