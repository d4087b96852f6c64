"""Benchmark: full-lattice sample rate the I2C bus allows vs what the compiled primary schedule reaches in the emulator.

The bus limit follows from the transaction bytes. --cells N [N ...]: the same for a sheet of N cells (the primary
polls them all, as its firmware built with -DMC_RIG_CELLS=N does; a chain scene of N cells stands in for the sheet:
the bus does not see the bands).

--image: the flashed primary and cell images of the image tier (16 cells; needs the images built): the cycles per
second the primary itself reports in its heartbeat (PRIMARY_STATUS.cycles) and the samples per cell it sent.

python -m host_emulator.benchmarks.bus [--seconds 5] [--cells 16 32 64] [--image]
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from protocol import wire

from ..bus.i2c import I2CTiming, lattice_rate_limit
from ..bus.rig import BusOptions, EmulatedRig, make_rig


def measure(
    hz: int, seconds: float, cells: int | None = None, **faults: Any
) -> tuple[float, float, EmulatedRig, dict[int, float]]:
    """(cycles per simulated second after a 0.5 s settle, wall seconds, rig, samples/s per cell); cells: a scene of
    that many cells (default the scene's 16)."""
    rig, _ = make_rig("exp5_rest", BusOptions(i2c_hz=hz, **faults), overrides=[f"cells={cells}"] if cells else ())
    n = max(rig.n, wire.N_CELLS)
    rig.advance_to(500_000)
    rig.frames()
    c0 = rig.p.cycles
    t0 = time.perf_counter()
    step = 20_000 if n <= wire.N_CELLS else 2_000  # a bigger sheet's frames popped as often as its cycle needs
    t = 500_000
    per_cell = {j: 0 for j in range(1, n + 1)}
    while t < 500_000 + seconds * 1e6:
        t += step
        rig.advance_to(t)
        for fid, _ in rig.frames():
            kind, j = wire.frame_kind(fid, n)
            if kind == "CELL_SAMPLE" and j is not None:  # a per-cell frame always has its cell
                per_cell[j] += 1
    return ((rig.p.cycles - c0) / seconds, time.perf_counter() - t0, rig, {j: c / seconds for j, c in per_cell.items()})


def sheet_rates(cells: list[int], seconds: float) -> None:
    """Per cell count: the 400 kHz bus bound, the emulated primary's rate, the same with a pessimistic glue."""
    tm = I2CTiming(400_000)
    n_bytes = wire.block_len("SNAPSHOT")
    print(
        f"I2C 400 kHz, one snapshot read of {n_bytes} bytes per cell per cycle = {tm.bits(n_bytes)} bit periods + "
        f"t_BUF = {tm.transaction_s(n_bytes) * 1e6:.1f} us"
    )
    for n in cells:
        limit = lattice_rate_limit(400_000, cells=n)
        rate, wall, rig, per = measure(400_000, seconds, cells=n)
        slow, _, _, _ = measure(400_000, seconds, cells=n, sw_overhead_us=40, stretch_us=20)
        print(
            f"  {n:2d} cells: bound {limit:7.2f} Hz per cell (cycle {1e3 / limit:6.2f} ms); emulated primary "
            f"{rate:7.2f} Hz = {100 * rate / limit:.1f} % (every cell >= {min(per.values()):.1f} samples/s); "
            f"40 us software + 20 us stretch per read: {slow:7.2f} Hz = {100 * slow / limit:.1f} %"
        )


def image_rate(seconds: float) -> None:
    """The flashed images (model image, scene exp5_rest): the primary's heartbeat (PRIMARY_STATUS.cycles: full
    cycles in its last second) and CELL_SAMPLE frames per cell over `seconds` of board time after a 0.5 s settle,
    read through the primary's own SLCAN on the emulated USB."""
    rig, sc = make_rig("exp5_rest", overrides=["model=image"])
    rig.session()  # the laptop opens the port (DTR up) and the channel
    rig.feed(b"O\r")
    lines: list[bytes] = []
    buf = b""
    t = 0
    while t < 500_000 + seconds * 1e6:
        t += 20_000
        rig.advance_to(t)
        buf += rig.drain()
        *done, buf = buf.split(b"\r")
        if t > 500_000:
            lines += [ln for ln in done if ln[:1] == b"t"]
    per_cell = dict.fromkeys(range(1, sc.cells + 1), 0)
    beats = []
    for ln in lines:
        fid, data = int(ln[1:4], 16), bytes.fromhex(ln[5 : 5 + 2 * int(ln[4:5], 16)].decode())
        kind, j = wire.frame_kind(fid)
        if kind == "CELL_SAMPLE" and j is not None:
            per_cell[j] += 1
        elif kind == "PRIMARY_STATUS":
            beats.append(int.from_bytes(data[4:6], "little"))
    limit = lattice_rate_limit(400_000, cells=sc.cells)
    print(
        f"image tier, the flashed primary and {sc.cells} cells at 400 kHz, {seconds:g} s of board time: heartbeats "
        f"say {beats} full cycles per second (bound {limit:.2f} Hz); CELL_SAMPLE per cell "
        f"{min(per_cell.values()) / seconds:.1f}..{max(per_cell.values()) / seconds:.1f} /s"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.bus",
        description=__doc__.split("\n\n")[0],
        epilog="example: python -m host_emulator.benchmarks.bus --seconds 2",
    )
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per measurement")
    ap.add_argument(
        "--cells",
        type=int,
        nargs="+",
        default=None,
        metavar="N",
        help=f"a sheet of N cells (1..{wire.MAX_CELLS}): the bound and the emulated primary at 400 kHz, each N",
    )
    ap.add_argument(
        "--image",
        action="store_true",
        help="the image tier's flashed primary and 16 cells: its own heartbeat's cycles per second (slow: minutes)",
    )
    args = ap.parse_args(argv)
    if args.image:
        image_rate(args.seconds)
        return 0
    if args.cells:
        wrong = [c for c in args.cells if not 1 <= c <= wire.MAX_CELLS]
        if wrong:
            print(f"error: --cells {wrong[0]}: expected 1..{wire.MAX_CELLS}", file=sys.stderr)
            return 2
        sheet_rates(args.cells, args.seconds)
        return 0
    n = wire.block_len("SNAPSHOT")
    for hz in (400_000, 100_000):
        tm = I2CTiming(hz)
        limit = lattice_rate_limit(hz)
        rate, wall, rig, _ = measure(hz, args.seconds)
        print(
            f"I2C {hz // 1000} kHz: snapshot read = {n} bytes = {tm.bits(n)} bit periods "
            f"({tm.transaction_s(n) * 1e6:.1f} us incl. t_BUF) per cell, {wire.N_CELLS} cells"
        )
        print(f"  bus-limited full-lattice rate : {limit:8.2f} Hz")
        print(
            f"  emulated primary schedule     : {rate:8.2f} Hz  = {100 * rate / limit:.1f} % of the limit "
            f"(sw overhead {rig.opts.sw_overhead_us} us/transaction; {wall / args.seconds:.3f} s wall per s)"
        )
    rate, _, _, _ = measure(400_000, args.seconds, sw_overhead_us=40, stretch_us=20)
    print(
        f"400 kHz, pessimistic glue (40 us software per transaction, 20 us clock stretch per read): "
        f"{rate:.2f} Hz = {100 * rate / lattice_rate_limit(400_000):.1f} % of the limit"
    )
    bad = (3, 7, 11)
    _, _, rig, per = measure(400_000, args.seconds, absent=(3,), stuck=(7,), babble=(11,))
    worst = min(r for j, r in per.items() if j not in bad)
    print(
        f"400 kHz with cell 3 absent, 7 stuck, 11 babbling: every other cell still gets >= {worst:.2f} samples/s "
        f"({100 * worst / lattice_rate_limit(400_000):.1f} % of the healthy bus limit); "
        f"timeouts {rig.p.cell[6].timeout}, skipped {rig.p.cell[6].skipped}, "
        f"NACKs {rig.p.cell[2].nack}, integrity errors {rig.p.cell[10].integrity}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
