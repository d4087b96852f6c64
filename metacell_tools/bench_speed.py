"""Print the emulator's real-time factor on one core (same as `python -m host_emulator bench-speed`)."""

import sys

from host_emulator.benchmarks.speed import bench_main

if __name__ == "__main__":
    sys.exit(bench_main(sys.argv[1:]))
