"""`python -m host_emulator plot PATH`: the figures of a run directory, an experiment directory or a capture (anything
he.load opens) as PNG, PDF or SVG, at screen size or one paper column wide."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..outpaths import check_out_dir
from .plots import FORMATS


def plot_main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator plot",
        description="Figures of a run or capture (anything he.load opens): spacetime (a 2-D sheet: snapshots), "
        "final_pattern and, when the run carries its parameters, dispersion.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator plot out/default --format pdf --column      # paper figures beside the run\n"
        "  python -m host_emulator plot out/rig1.npz --out figs --format svg   # a logger capture\n"
        "exit codes: 0 ok, 2 bad input (a path it cannot read, an output it cannot write).",
    )
    ap.add_argument("path", help="run directory, experiment directory, logger capture, python-can log, NPZ or NetCDF")
    ap.add_argument("--out", default=None, help="output directory (default: PATH itself if a directory, else its own)")
    ap.add_argument("--format", choices=FORMATS, default="png", help="file format (default png)")
    ap.add_argument("--column", action="store_true", help="one paper column wide (3.4 in), fonts to match")
    ap.add_argument("--source", default=None, help="label of data whose file does not say (rig, emulator:<model>)")
    ap.add_argument("--repeat", type=int, default=None, help="an experiment directory's repeat (default its first)")
    args = ap.parse_args(argv)
    from .datasets import LoadError, load
    from .inputs import as_run
    from .plots import plot_run

    src = Path(args.path)
    try:
        out = Path(args.out) if args.out else (src if src.is_dir() else src.parent)
        made = not out.exists()  # removed again (if still empty) when the input is refused
    except OSError:  # a name too long for the file system: check_out_dir or load says so
        out, made = Path(args.out) if args.out else src.parent, False
    problem = check_out_dir(out) if args.out else None  # a given --out: checked before any work
    if problem:
        print(f"plot: error: {problem}", file=sys.stderr)
        return 2
    try:
        ds = load(src, source=args.source, repeat=args.repeat)
        if ds.sizes.get("time", 0) < 1:
            raise LoadError(f"{src}: no samples")
    except (LoadError, OSError, ValueError) as e:
        if made and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # nothing left behind
        print(f"plot: error: {e}", file=sys.stderr)
        return 2
    problem = check_out_dir(out)
    if problem:
        print(f"plot: error: {problem}", file=sys.stderr)
        return 2
    files = plot_run(as_run(ds), None, out, fmt=args.format, column=args.column)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0
