"""Vectors for the SLCAN codec: lines in a given channel state, and frames to encode; expected by a Lawicel model."""

from __future__ import annotations

import random

HEXD = set("0123456789abcdefABCDEF")
EFF = 0x80000000
RTR = 0x40000000


def model(line: str, is_open: bool, listen: bool) -> tuple[str, str, tuple[int, int, bytes] | None]:
    """Reference: (kind, reply, frame) for one line; kind in none/reply/frame/error."""
    if line == "":
        return "none", "", None
    if any(not (0x20 <= ord(c) <= 0x7E) for c in line) or len(line) > 32:
        return "error", "\a", None
    c, rest = line[0], line[1:]
    simple = {"O": "\r", "L": "\r", "C": "\r", "V": "V0101\r", "v": "v0101\r", "N": "NMC01\r", "F": "F00\r"}
    if c in simple:
        return ("reply", simple[c], None) if rest == "" else ("error", "\a", None)
    if c == "S":
        return ("reply", "\r", None) if len(rest) == 1 and rest in "012345678" else ("error", "\a", None)
    if c == "s":
        return ("reply", "\r", None) if len(rest) == 4 and set(rest) <= HEXD else ("error", "\a", None)
    if c == "Z":
        return ("reply", "\r", None) if rest in ("0", "1") else ("error", "\a", None)
    if c in "Mm":
        return ("reply", "\r", None) if len(rest) == 8 and set(rest) <= HEXD else ("error", "\a", None)
    if c in "tTrR":
        if not is_open or listen:
            return "error", "\a", None
        n = 8 if c in "TR" else 3
        if len(rest) < n + 1 or not set(rest[: n + 1]) <= HEXD or rest[n] not in "0123456789":
            return "error", "\a", None
        fid, dlc = int(rest[:n], 16), int(rest[n])
        if dlc > 8 or fid > (0x7FF if n == 3 else 0x1FFFFFFF):
            return "error", "\a", None
        body = rest[n + 1 :]
        if c in "rR":
            if body:
                return "error", "\a", None
            data = b""
        else:
            if len(body) != 2 * dlc or not set(body) <= HEXD:
                return "error", "\a", None
            data = bytes.fromhex(body)
        flags = (EFF if n == 8 else 0) | (RTR if c in "rR" else 0)
        return "frame", "Z\r" if n == 8 else "z\r", (fid | flags, dlc, data)
    return "error", "\a", None


def encode_reference(fid: int, data: bytes, timestamps: bool, ts_ms: int) -> str:
    """Lawicel text of a frame as python-can's slcan interface writes it ('' for an invalid frame)."""
    ext, rtr, ident = bool(fid & EFF), bool(fid & RTR), fid & 0x1FFFFFFF
    if len(data) > 8 or (not ext and ident > 0x7FF):
        return ""
    kind = ("R" if ext else "r") if rtr else ("T" if ext else "t")
    text = kind + (f"{ident:08X}" if ext else f"{ident:03X}") + str(len(data)) + ("" if rtr else data.hex().upper())
    if timestamps:
        text += f"{ts_ms % 60000:04X}"
    return text + "\r"


def line_case(name: str, state: str, line: str) -> dict:
    """state: 'closed', 'open' (after O) or 'listen' (after L)."""
    kind, reply, frame = model(line, state != "closed", state == "listen")
    return {"name": name, "state": state, "line": line, "kind": kind, "reply": reply, "frame": frame}


_HAND = [
    ("closed", "t1002AABB"),
    ("open", "t1002AABB"),
    ("listen", "t1002AABB"),
    ("open", "T1FFFFFFF3010203"),
    ("open", "T200000000"),
    ("open", "r7FF8"),
    ("open", "R000001238"),
    ("open", "r7FF81"),
    ("open", "t8000"),
    ("open", "t1009"),
    ("open", "t1001"),
    ("open", "t1001GG"),
    ("open", "t10"),
    ("open", "t" + "1" * 40),
    ("open", "t10\x0012"),
    ("open", "t1000"),
    ("open", ""),
    ("closed", "O"),
    ("closed", "L"),
    ("open", "C"),
    ("closed", "O1"),
    ("closed", "V"),
    ("closed", "v"),
    ("closed", "N"),
    ("closed", "F"),
    ("closed", "S6"),
    ("closed", "S9"),
    ("closed", "s031C"),
    ("closed", "s031"),
    ("closed", "Z1"),
    ("closed", "Z2"),
    ("closed", "M00000000"),
    ("closed", "mFFFFFFFF"),
    ("closed", "m0000000G"),
    ("closed", "x"),
    ("closed", "\x7f"),
]

ALPHABET = list("tTrRSsOLCVvNFZMmx0123456789abcdefABCDEFG \x07\x7f")


def _random_lines(n: int, seed: int = 0x51CA) -> list[tuple[str, str]]:
    """Seeded lines of the property test's three shapes: any text, well-formed t/r frames, T frames (some too big)."""
    rnd = random.Random(seed)
    out = []
    for k in range(n):
        state = ("closed", "open", "listen")[rnd.randrange(3)]
        shape = k % 3
        if shape == 0:
            line = "".join(rnd.choice(ALPHABET) for _ in range(rnd.randrange(31)))
        elif shape == 1:
            d = bytes(rnd.randrange(256) for _ in range(rnd.randrange(9)))
            ident = "".join(rnd.choice("0123456789ABCDEF") for _ in range(3))
            line = rnd.choice("tr") + ident + str(len(d)) + d.hex()
        else:
            d = bytes(rnd.randrange(256) for _ in range(rnd.randrange(9)))
            line = "T" + f"{rnd.randrange(0x40000000):08X}" + str(len(d)) + d.hex()
        out.append((state, line))
    return out


LINE_CASES = [line_case(f"hand_{k}", s, ln) for k, (s, ln) in enumerate(_HAND)] + [
    line_case(f"random_{k}", s, ln) for k, (s, ln) in enumerate(_random_lines(300))
]


def _encode_cases(n: int, seed: int = 0xE4C0) -> list[dict]:
    rnd = random.Random(seed)
    raw = [
        (0x800, b"", False, 0),  # 11-bit id out of range
        (0x7FF, bytes(range(8)), False, 0),
        (EFF | 0x1FFFFFFF, b"\xff", True, 59999),
        (RTR | 0x123, bytes(3), False, 0),
        (EFF | RTR | 0x12345, bytes(8), True, 2**32 - 1),
    ]
    for _ in range(n):
        ext = rnd.random() < 0.5
        fid = rnd.randrange(0x20000000) if ext else rnd.randrange(0x800)
        d = bytes(rnd.randrange(256) for _ in range(rnd.randrange(9)))
        raw.append(((EFF if ext else 0) | fid, d, rnd.random() < 0.5, rnd.randrange(2**32)))
    return [
        {"id": f, "data": d, "timestamps": ts_on, "ts_ms": ts, "text": encode_reference(f, d, ts_on, ts)}
        for f, d, ts_on, ts in raw
    ]


ENCODE_CASES = _encode_cases(120)
