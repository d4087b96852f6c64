"""Vectors for the cell register handler: one write to a fresh cell, then a tick; expected by a reference model."""

from __future__ import annotations

import random
import struct

from metacell_tools.rigtools import proto

D = proto.D
J = 5  # the cell under test
ADDR = proto.cell_address(J)
BUILD = 0xC0FFEE
# parameters in force after mc_cell_default_params (the PARAMS block's i32 fields, in block order)
DEFAULTS = {"K_AB": 20000, "SIGMA": 72000, "K1": 60000, "K2": -60000, "ASTAR": 1178097}
PARAM_REGS = tuple(DEFAULTS)
MAX_PAYLOAD = max(sum(D.TYPE_SIZES[f[1]] for f in r["payload"]) for r in D.REGISTERS.values())


def sign(body: bytes) -> bytes:
    """Append the write CRC (over the address byte and the body) for cell J."""
    return body + bytes([proto.crc8(bytes([ADDR << 1]) + body)])


def reference_result(frame: bytes, addr: int = ADDR) -> str:
    """Independent model of the validation order: length, CRC, register, length, ranges (non-POINTER frames)."""
    if len(frame) < 3 or len(frame) > 3 + MAX_PAYLOAD:
        return "LENGTH"
    if proto.crc8(bytes([addr << 1]) + frame[:-1]) != frame[-1]:
        return "CRC"
    regs = {r["id"]: (k, r) for k, r in D.REGISTERS.items()}
    if frame[0] not in regs or regs[frame[0]][0] == "POINTER":
        return "REG"
    name, r = regs[frame[0]]
    if len(frame) != 3 + sum(D.TYPE_SIZES[f[1]] for f in r["payload"]):
        return "LENGTH"
    p = frame[2:-1]
    if name in PARAM_REGS:
        ph = dict(DEFAULTS)
        ph[name] = struct.unpack("<i", p)[0]
        kmax, amax = D.LIMITS["K_MAX_UNM"], D.LIMITS["ASTAR_MAX_URAD"]
        if any(abs(ph[k]) > kmax for k in ("K_AB", "SIGMA", "K1", "K2")) or not 0 <= ph["ASTAR"] <= amax:
            return "RANGE"
        if ph["K1"] <= ph["K2"] or ph["K1"] <= 0:
            return "SHAPE"
        return "OK"
    if name in ("ENABLE", "BEMF"):
        return "OK" if p[0] <= 1 else "RANGE"
    if name == "PERTURB":
        chain, t, _ = struct.unpack("<BhH", p)
        # the wire carries torque in TORQUE_WIRE_UNM LSBs; the cell accepts |torque| <= PERTURB_MAX_UNM uN*m
        return "OK" if chain <= 1 and abs(D.TORQUE_WIRE_UNM * t) <= D.LIMITS["PERTURB_MAX_UNM"] else "RANGE"
    if name == "PWM_LIMIT":
        return "OK" if struct.unpack("<H", p)[0] <= 2400 else "RANGE"
    return "OK"


def expect(name: str, frame: bytes) -> dict:
    """The vector for one frame: what the snapshot, the PARAMS block and the read pointer must show after a tick."""
    v = {"name": name, "frame": frame, "pointer": False, "read_tag": 0x10 | D.BLOCKS["SNAPSHOT"]["id"], "bus_err": 0}
    if frame and frame[0] == D.REGISTERS["POINTER"]["id"]:
        # applied at once (not a command): a valid one selects the block of the next read only
        valid = (
            len(frame) == 4 and proto.crc8(bytes([ADDR << 1]) + frame[:-1]) == frame[-1] and frame[2] < len(D.BLOCKS)
        )
        v.update(pointer=True, result="NONE", rejected=0, seq=0, bus_err=0 if valid else 1)
        v["read_tag"] = 0x10 | (frame[2] if valid else 0)
        v["params"] = tuple(DEFAULTS.values())
        return v
    if not frame:  # SAMD21: onReceive(0) after a read
        v.update(result="NONE", rejected=0, seq=0, params=tuple(DEFAULTS.values()))
        return v
    res = reference_result(frame)
    ph = dict(DEFAULTS)
    if res == "OK":
        reg = next(k for k, r in D.REGISTERS.items() if r["id"] == frame[0])
        if reg in PARAM_REGS:
            ph[reg] = struct.unpack("<i", frame[2:-1])[0]
    v.update(
        result=res, rejected=0 if res == "OK" else 1, seq=frame[1] if res == "OK" else 0, params=tuple(ph.values())
    )
    return v


def _write(reg: str, seq: int, **values) -> bytes:
    return proto.i2c_write_frame(J, reg, seq, proto.pack_payload(reg, **values))


def _hand_picked() -> list[tuple[str, bytes]]:
    enable = _write("ENABLE", 1, on=1)
    out = [
        ("sigma_ok", _write("SIGMA", 7, value=48000)),
        ("k_ab_ok", _write("K_AB", 1, value=15000)),
        ("k1_ok", _write("K1", 2, value=70000)),
        ("k2_ok", _write("K2", 3, value=-1000)),
        ("astar_ok", _write("ASTAR", 4, value=6283185)),
        ("enable_ok", enable),
        ("bemf_ok", _write("BEMF", 2, on=0)),
        ("perturb_ok", _write("PERTURB", 1, chain=1, torque=-1000, ticks=30)),
        ("pwm_limit_ok", _write("PWM_LIMIT", 3, ticks=100)),
        ("zero_ok", _write("ZERO", 9)),
        ("clear_faults_ok", _write("CLEAR_FAULTS", 5)),
        ("bad_crc", enable[:-1] + bytes([enable[-1] ^ 0x20])),
        ("other_cell", proto.i2c_write_frame(J + 1, "ENABLE", 1, b"\x01")),
        ("unknown_register", sign(bytes([0x7E, 1, 0, 0]))),
        ("short_payload", sign(bytes([D.REGISTERS["K_AB"]["id"], 1, 0, 0]))),
        ("overlong", bytes(40)),
        ("two_bytes", b"\x20\x01"),
        ("empty", b""),
        ("k_ab_range", _write("K_AB", 0x42, value=250001)),
        ("astar_negative", _write("ASTAR", 0x42, value=-1)),
        ("k1_shape", _write("K1", 0x42, value=-70000)),
        ("k2_shape", _write("K2", 0x42, value=60000)),
        ("enable_range", _write("ENABLE", 0x42, on=2)),
        ("bemf_range", _write("BEMF", 0x42, on=255)),
        ("perturb_chain", _write("PERTURB", 0x42, chain=2, torque=1, ticks=1)),
        ("perturb_torque", _write("PERTURB", 0x42, chain=0, torque=32767, ticks=1)),
        ("pwm_limit_range", _write("PWM_LIMIT", 0x42, ticks=5000)),
        ("pointer_ident", _write("POINTER", 0, block=D.BLOCKS["IDENT"]["id"])),
        ("pointer_params", _write("POINTER", 0, block=D.BLOCKS["PARAMS"]["id"])),
        ("pointer_no_block", _write("POINTER", 0, block=9)),
    ]
    ptr = _write("POINTER", 0, block=1)
    out.append(("pointer_bad_crc", ptr[:-1] + bytes([ptr[-1] ^ 1])))
    return out


def _random(n: int, seed: int = 0x5EC5) -> list[tuple[str, bytes]]:
    """Seeded frames of the three shapes the property test draws: raw bytes, POINTER writes, signed writes."""
    rnd = random.Random(seed)
    ids = [r["id"] for r in D.REGISTERS.values()] + [0x7F]
    out = []
    for k in range(n):
        shape = k % 3
        if shape == 0:
            f = bytes(rnd.randrange(256) for _ in range(rnd.randrange(17)))
        elif shape == 1:
            f = sign(bytes([D.REGISTERS["POINTER"]["id"], rnd.randrange(256), rnd.randrange(5)]))
        else:
            reg = rnd.choice(ids)
            f = sign(bytes([reg, rnd.randrange(256)]) + bytes(rnd.randrange(256) for _ in range(rnd.randrange(9))))
        out.append((f"random_{k}", f))
    return out


CASES = [expect(name, frame) for name, frame in _hand_picked() + _random(150)]
