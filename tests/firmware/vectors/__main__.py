"""`python -m tests.firmware.vectors OUT_DIR`: write the C headers of the bus vectors for the Unity suites."""

import argparse
from pathlib import Path

from .cheader import write_headers


def main() -> None:
    ap = argparse.ArgumentParser(prog="python -m tests.firmware.vectors", description=__doc__)
    ap.add_argument("out_dir", type=Path, help="directory for bus_vectors_*.h (a build directory)")
    for p in write_headers(ap.parse_args().out_dir):
        print(f"vectors: {p}")


if __name__ == "__main__":
    main()
