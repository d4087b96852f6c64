"""Benchmark: the emulated rig day, `python -m metacell_tools.flash flash --emulated` on 17 blank boards (bossac
writes each board's image through the XIAO bootloader), timed with the boards on one thread and on two.

python -m host_emulator.benchmarks.flash [--threads 1 2] [--reps 1] [--usb-packet-us 50]

Needs MC_BOOTLOADER, bossac and the images (built now if the image tier's cache lacks them, not timed: the flash tool
gets them with --prebuilt). Each rep is one whole command: the boards' start, 17 uploads at once (--jobs 17),
17 returns and `ID?`s, the stop. The emulated USB host moves one packet every `usb_packet_us` microseconds of board
time (64 bytes: 1.28 MB/s at 50 us, above what bossac gets from a real XIAO's full-speed port).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..image.build import build_images

ROOT = Path(__file__).resolve().parents[2]


def prebuilt(out: Path) -> Path:
    images = build_images(16, primary=True)
    for j, elf in enumerate(images.cells, 1):
        (out / f"cell{j:02d}").mkdir(parents=True, exist_ok=True)
        shutil.copy(elf, out / f"cell{j:02d}" / "firmware.elf")
    (out / "primary").mkdir(exist_ok=True)
    shutil.copy(images.primary, out / "primary" / "firmware.elf")
    return out


def one(images: Path, threads: int, usb_packet_us: float, logs: Path) -> float:
    argv = [sys.executable, "-m", "metacell_tools.flash", "flash", "--emulated", "--prebuilt", str(images)]
    argv += ["--keep-going", "--log-dir", str(logs), f"--emulated-arg=--set=model_options.image.threads={threads}"]
    argv += [f"--emulated-arg=--usb-packet-us={usb_packet_us:g}"]
    t0 = time.monotonic()
    r = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
    took = time.monotonic() - t0
    if r.returncode != 0 or "17 of 17 board(s) flashed and verified" not in r.stdout:
        raise SystemExit(f"the emulated flash failed (exit {r.returncode}):\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
    return took


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.flash", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="board threads to time (default 1 2)")
    ap.add_argument("--reps", type=int, default=1, help="runs per thread count; the median is shown (default 1)")
    ap.add_argument("--usb-packet-us", type=float, default=50.0, help="the emulated USB's packet time (default 50)")
    args = ap.parse_args(argv)
    if not os.environ.get("MC_BOOTLOADER") or not shutil.which("bossac"):
        print("flash benchmark: needs MC_BOOTLOADER (the XIAO bootloader's .bin) and bossac", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="mc-flash-bench-") as tmp:
        images = prebuilt(Path(tmp) / "images")
        rate = 1e6 / args.usb_packet_us
        print(
            f"17 blank emulated boards, flash --emulated --jobs 17; emulated USB: one packet per "
            f"{args.usb_packet_us:g} us ({rate:,.0f} packets/s, {rate * 64 / 1e6:.2f} MB/s of 64-byte packets)"
        )
        for n in args.threads:
            times = [one(images, n, args.usb_packet_us, Path(tmp) / "logs") for _ in range(args.reps)]
            runs = ", ".join(f"{t:.1f}" for t in times)
            print(f"  {n} thread(s): {statistics.median(times):6.1f} s wall (runs: {runs})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
