"""Benchmark: full-lattice sample rate the I2C bus allows vs what the compiled primary schedule reaches in the emulator.

The bus limit follows from the transaction bytes.

python -m host_emulator.benchmarks.bus [--seconds 5]
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from protocol import wire

from ..bus.i2c import I2CTiming, lattice_rate_limit
from ..bus.rig import BusOptions, EmulatedRig, make_rig


def measure(hz: int, seconds: float, **faults: Any) -> tuple[float, float, EmulatedRig, dict[int, float]]:
    """(cycles per simulated second after a 0.5 s settle, wall seconds, rig, samples/s per cell)."""
    rig, _ = make_rig("exp5_rest", BusOptions(i2c_hz=hz, **faults))
    rig.advance_to(500_000)
    rig.frames()
    c0 = rig.p.cycles
    t0 = time.perf_counter()
    step = 20_000
    t = 500_000
    per_cell = {j: 0 for j in range(1, wire.N_CELLS + 1)}
    while t < 500_000 + seconds * 1e6:
        t += step
        rig.advance_to(t)
        for fid, _ in rig.frames():
            kind, j = wire.frame_kind(fid)
            if kind == "CELL_SAMPLE" and j is not None:  # a per-cell frame always has its cell
                per_cell[j] += 1
    return ((rig.p.cycles - c0) / seconds, time.perf_counter() - t0, rig, {j: c / seconds for j, c in per_cell.items()})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.bus",
        description=__doc__.split("\n\n")[0],
        epilog="example: python -m host_emulator.benchmarks.bus --seconds 2",
    )
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per measurement")
    args = ap.parse_args(argv)
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
