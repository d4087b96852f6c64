"""`python -m host_emulator image ...`: the flashed images on the image tier's boards: build them, list the registers
each touches, profile where each spends its cycles.

    image build                     build (or find cached) the 16 cell images and the primary's; print their paths
    image registers [--board B]     run the boards from power-up, the laptop configuring the cells as a run does,
                                    and list every register each image read or wrote (reads, writes)
    image profile [--board B]       the same run; CPU cycles per function of a board's image, most first
    image nvic [--board B]          the same run; the NVIC priorities each image programmed (0 most urgent), read
                                    back from its NVIC: every enabled interrupt

Exit codes: 0 ok, 2 bad arguments, 3 the images cannot be built or the run failed.
"""

from __future__ import annotations

import argparse
import bisect
import json
import sys

import numpy as np


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator image",
        description="The flashed firmware images on the image tier (docs/image-tier.md).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator image build\n"
        "  python -m host_emulator image registers --board cell1 --board primary\n"
        "  python -m host_emulator image profile --board primary --seconds 0.5\n"
        "  python -m host_emulator image nvic --board cell1 --board primary\n",
    )
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="COMMAND", help="what to do with the images")
    sub.add_parser(
        "build",
        help="build (or find cached) the images; print their paths",
        epilog="example: python -m host_emulator image build",
    )
    for name, what, example in (
        ("registers", "list every register each image touched", "registers --board cell1 --board primary"),
        ("profile", "cycles per function", "profile --board primary --seconds 0.5 --top 10"),
        ("nvic", "the NVIC priorities each image programmed", "nvic --board cell1 --board primary"),
    ):
        p = sub.add_parser(name, help=what, epilog=f"example: python -m host_emulator image {example}")
        p.add_argument("--board", action="append", default=[], help="cellN or primary (default: all / primary)")
        p.add_argument("--seconds", type=float, default=0.5, help="time run after the cells are configured (s)")
        p.add_argument("--json", action="store_true", help="JSON on stdout")
        if name == "profile":
            p.add_argument("--top", type=int, default=25, help="functions listed per board (default 25)")
    return ap


def _boards(world, names: list[str], default: list[str]) -> list:
    by_name = {b.name.replace(" ", ""): b for b in world.boards}
    out = []
    for n in names or default:
        key = n.replace(" ", "").lower()
        if key not in by_name:
            raise ValueError(f"--board {n!r}: expected one of {', '.join(by_name)}")
        out.append(by_name[key])
    return out


def _bring_up(seconds: float, profile_boards: list[str] | None = None):
    from ..params import Params
    from .build import build_images
    from .model import bring_up
    from .world import World

    p = Params(cells=16)
    w = World(p, build_images(16))
    boards = [] if profile_boards is None else _boards(w, profile_boards, [])
    lap, _ = bring_up(w, p, progress=True)
    w.start_plant()
    for b in boards:  # the profile counts from here: the first call starts it (bring-up is not in the figures)
        w.profile(b.index)
    lap.pump(seconds)
    return w


def image_main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from ..models.options import ConfigError
    from . import ImageTierUnavailable
    from .build import build_images
    from .world import WorldError

    for name in getattr(args, "board", []):
        key = name.replace(" ", "").lower()
        if not (key == "primary" or (key.startswith("cell") and key[4:].isdigit() and 1 <= int(key[4:]) <= 16)):
            print(f"image: --board {name!r}: expected cell1..cell16 or primary", file=sys.stderr)
            return 2

    if getattr(args, "seconds", 1.0) is not None and not 0 < getattr(args, "seconds", 1.0) <= 60:
        print("image: --seconds must be in (0, 60]", file=sys.stderr)
        return 2
    if getattr(args, "top", 1) < 1:
        print(f"image: --top {args.top}: expected a positive number of functions", file=sys.stderr)
        return 2
    try:
        if args.cmd == "build":
            s = build_images(16)
            for j, f in enumerate(s.cells, 1):
                print(f"cell {j:2d}  {f}")
            print(f"primary  {s.primary}")
            return 0
        if args.cmd == "registers":
            w = _bring_up(args.seconds)
            boards = _boards(w, args.board, [b.name.replace(" ", "") for b in w.boards])
            table = {
                b.name: [{"register": r, "reads": rd, "writes": wr} for r, rd, wr in w.touched(b.index)] for b in boards
            }
            if args.json:
                json.dump(table, sys.stdout, indent=1)
                print()
            else:
                for name, regs in table.items():
                    print(f"{name}: {len(regs)} registers")
                    for r in regs:
                        print(f"  {r['register']:<40} {r['reads']:>9} reads {r['writes']:>9} writes")
            return 0
        if args.cmd == "nvic":
            w = _bring_up(args.seconds)
            boards = _boards(w, args.board, [b.name.replace(" ", "") for b in w.boards])
            nvic_report = {b.name: nvic_priorities(w, b.index) for b in boards}
            if args.json:
                json.dump(nvic_report, sys.stdout, indent=1)
                print()
            else:
                for name, prios in nvic_report.items():
                    print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in prios.items()))
            return 0
        # profile
        names = args.board or ["primary"]
        w = _bring_up(args.seconds, names)
        report = {}
        for b in _boards(w, names, []):
            report[b.name] = by_function(w.profile(b.index), b.image)
        if args.json:
            json.dump(report, sys.stdout, indent=1)
            print()
        else:
            for name, funcs in report.items():
                total = sum(c for _, c in funcs) or 1
                print(f"{name}: {total:,} cycles in {args.seconds} s after configuration")
                for fn, c in funcs[: args.top]:
                    print(f"  {100 * c / total:5.1f} %  {c:>12,}  {fn}")
        return 0
    except (ImageTierUnavailable, WorldError) as e:
        print(f"image: {e}", file=sys.stderr)
        return 3
    except (ConfigError, ValueError) as e:
        print(f"image: {e}", file=sys.stderr)
        return 2


def nvic_priorities(world, b: int) -> dict[str, int]:
    """The priority (0..3, 0 most urgent) of every interrupt enabled in board b's NVIC, as the image programmed
    them (read back from the NVIC, wherever the image set them), most urgent first."""
    from metacell_common.target.vectors import IRQN

    i = world.info(b)
    names = {n: name for name, n in IRQN.items()}
    out = {names.get(n, f"IRQ{n}"): int(i.nvic_prio[n]) for n in range(32) if int(i.nvic_enabled) >> n & 1}
    return dict(sorted(out.items(), key=lambda kv: kv[1]))


def by_function(profile: np.ndarray, image) -> list[tuple[str, int]]:
    """Cycles per function (block start addresses mapped through the ELF's symbols), most first."""
    funcs = sorted((a, n, sz) for n, (a, sz) in image.symbols.items() if sz and a < 2 * len(profile))
    starts = [f[0] for f in funcs]
    out: dict[str, int] = {}
    for h in np.nonzero(profile)[0]:
        a = int(h) * 2
        i = bisect.bisect_right(starts, a) - 1
        name = funcs[i][1] if i >= 0 and a < funcs[i][0] + funcs[i][2] else f"0x{a:05x}"
        out[name] = out.get(name, 0) + int(profile[h])
    return sorted(out.items(), key=lambda kv: -kv[1])


if __name__ == "__main__":  # pragma: no cover
    sys.exit(image_main())
