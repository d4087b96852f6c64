"""Rig logger on python-can: log files, decoded alpha_j(t)/beta_j(t) arrays (NPZ, CSV), gap reports, reconnects.

The command line of `python -m metacell_tools.rigtools.logger` (the console script metacell-logger): its arguments,
the output checks before the port is opened, --repair, and the summary line (the package docstring has the rest).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from metacell_common.cli import unexpected
from metacell_common.outpaths import check_out_dir, check_out_file, created_mark, remove_created_since, show
from protocol.wire import N_CELLS

from .. import rigconfig
from ..command import build, parser
from .files import RunFailed, repair
from .live import RigLogger

DESCRIPTION = __doc__.split("\n\n")[0]


def check_out(prefix: Path, formats: Sequence[str]) -> str | None:
    """Why the output prefix cannot be written, or None (creates its directory and probes every file it will
    write: a read-only place or a name too long fails here, before the port is opened)."""
    if prefix.name in ("", ".", ".."):
        return f"--out {show(prefix)}: needs a file name prefix, e.g. out/run1"
    problem = check_out_dir(prefix.parent, f"--out {show(prefix)}: directory")
    if problem:
        return problem
    for f in list(dict.fromkeys(list(formats) + ["csv", "npz", "npz.tmp"])):
        problem = check_out_file(prefix.with_suffix("." + f), "--out")
        if problem:
            return problem
    return None


CAPTURE_FILES = ("csv", "npz", "asc", "blf", "db", "log", "trc", "txt", "mf4")  # every file a run may write


def held_capture(prefix: Path) -> tuple[int, list[Path]] | None:
    """(samples, files) when prefix names a capture that holds data, else None. The CSV is what every run writes
    and --repair rebuilds from: a capture holds data when its CSV has a row or its NPZ a sample; without either, a
    non-empty log file of the prefix counts. A run that recorded no frame (a port that never opened) holds none."""
    try:
        files = [p for p in (prefix.with_suffix("." + f) for f in CAPTURE_FILES) if p.is_file()]
    except OSError:  # a name too long, a place no one may look: check_out says why
        return None
    if not files:
        return None
    csv, npz = prefix.with_suffix(".csv"), prefix.with_suffix(".npz")
    rows = 0
    if csv.is_file():
        with open(csv, "rb") as f:
            rows = max(0, sum(1 for line in f if line.strip()) - 1)
    if not rows and npz.is_file():
        try:
            with np.load(npz, allow_pickle=False) as z:
                key = "alpha" if "alpha" in z.files else "alpha_counts" if "alpha_counts" in z.files else None
                rows = int(np.sum(~np.isnan(z[key]))) if key else 0
        except Exception:  # noqa: BLE001 - an NPZ that does not read is still a file someone may want
            rows = -1
    if rows or (not (csv.is_file() or npz.is_file()) and any(p.stat().st_size for p in files)):
        return rows, files
    return None


def main(argv: list[str] | None = None) -> int:
    mark = created_mark()
    try:
        rc = _main(argv)
    except Exception as e:  # noqa: BLE001 - the last guard: one line, never a traceback (MC_DEBUG=1 shows it)
        return unexpected(e, "logger")
    if rc == 2:
        remove_created_since(mark)  # a rejection leaves no empty directory behind
    return rc


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.rigtools.logger",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run1                 # until Ctrl-C\n"
        "  python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run2 --duration 30 --formats asc\n"
        '  python -m metacell_tools.rigtools.logger -c /dev/pts/3@115200 -o out/run3 --do "2:perturb 8 --torque 0.02 '
        '--duration 0.1"\n'
        "an --out that already holds a capture is refused (exit 2, nothing changed) unless --overwrite is given.\n"
        "exit codes: 0 ok (also after Ctrl-C, SIGTERM, SIGHUP), 2 bad input (also: --out holds a capture), "
        "3 run failed (port, no frames, write error).",
    )
    ap.add_argument("-i", "--interface", default="slcan", help="python-can interface (default slcan)")
    ap.add_argument("-c", "--channel", default=None, help="e.g. /dev/ttyACM0@115200 or <pty>@115200 (required)")
    ap.add_argument("-o", "--out", default=None, help="output prefix, e.g. out/run1 (required)")
    ap.add_argument(
        "--repair",
        metavar="PREFIX",
        default=None,
        help="after a crash, kill or full disk: cut the logs after their last complete record (BLF: object) and "
        "rebuild PREFIX.npz from PREFIX.csv; no port is opened",
    )
    ap.add_argument(
        "--formats", default="asc", help="python-can log formats, comma separated (asc,blf,csv,log,trc,...)"
    )
    ap.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the capture --out already names (default: refuse it, exit 2, nothing changed)",
    )
    ap.add_argument("--bitrate", type=int, default=None, help="CAN bit rate sent as Sn (ignored by the primary)")
    ap.add_argument(
        "--duration", type=float, default=None, help="seconds to log from the first frame (default: until Ctrl-C)"
    )
    ap.add_argument("--give-up", type=float, default=None, help="stop retrying a lost connection after this many s")
    ap.add_argument("--wait-open", type=float, default=0.0, help="keep trying to open the port this many s at start")
    ap.add_argument("--first-frame", type=float, default=30.0, help="fail if no frame arrives in this many s")
    ap.add_argument(
        "--source",
        default=None,
        metavar="LABEL",
        help="what sends the frames, written into the NPZ: rig, emulator:hil, rehearsal:hil or unknown (default: "
        "from the channel: a pty is the emulator's serve, a USB serial device the rig, else unknown; with --repair: "
        "the label of the rebuilt NPZ, default unknown)",
    )
    ap.add_argument(
        "--rig",
        default=None,
        metavar="TOML",
        help="the rig config (cells = [4, 4] for a 4 x 4 sheet; default rig/rig.toml when it exists, else the rig as "
        "built, a chain of 16): its cells are decoded and its topology written into the NPZ, so the capture is "
        "analysed as that sheet",
    )
    ap.add_argument(
        "--do",
        action="append",
        default=[],
        metavar="T:COMMAND",
        help="run a command-tool command T s after the first frame through the same port, "
        'e.g. --do "2:perturb 8 --torque 0.02 --duration 0.1"',
    )
    args = ap.parse_args(argv)

    def bad(text):
        print(f"logger: {text}", file=sys.stderr)
        return 2

    if args.source is not None and not (
        args.source in ("rig", "unknown") or args.source.split(":")[0] in ("emulator", "rehearsal")
    ):
        return bad(f"--source {args.source!r}: expected rig, emulator:<model>, rehearsal:<model> or unknown")
    try:
        rig = rigconfig.read(args.rig)
    except rigconfig.RigConfigError as e:
        return bad(str(e))
    n_cells = max(N_CELLS, rigconfig.n_cells(rig))  # the rig as built's 16, or a bigger sheet's every cell
    topology = None if rig == rigconfig.AS_BUILT else rig
    if args.repair is not None:
        try:
            arr = repair(Path(args.repair), n_cells, source=args.source, topology=topology)
        except RunFailed as e:
            return bad(str(e))
        except OSError as e:
            print(f"logger: --repair {args.repair}: write failed: {e.strerror or e}", file=sys.stderr)
            return 3
        print(
            f"repaired {args.repair}: {int(np.sum(~np.isnan(arr['alpha_counts'])))} samples in "
            f"{len(arr['cycle'])} cycles, {len(arr['gaps'])} gaps; wrote {args.repair}.npz"
        )
        return 0
    if not args.channel or not args.out:
        ap.error("the following arguments are required: -c/--channel, -o/--out (or --repair PREFIX)")

    for name in ("duration", "give_up", "wait_open", "first_frame"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and 0 <= v <= 1e7 and (v > 0 or name == "wait_open")):
            return bad(f"--{name.replace('_', '-')} must be a finite number of seconds in (0, 1e7], got {v}")
    if args.bitrate is not None and not 1 <= args.bitrate <= 1_000_000:
        return bad(f"--bitrate must be in 1..1000000, got {args.bitrate}")
    formats = [f.strip().lstrip(".") for f in args.formats.split(",") if f.strip()]
    known = ("asc", "blf", "csv", "db", "log", "trc", "txt", "mf4")
    if not formats or any(f not in known for f in formats):
        return bad(f"--formats: expected some of {','.join(known)}, got {args.formats!r}")
    commands = []
    for item in args.do:  # checked before anything is written; argparse's usage text is no part of the line
        t, sep, text = item.partition(":")
        said = io.StringIO()
        try:
            tt = float(t)
            if not (sep and math.isfinite(tt) and tt >= 0):
                raise ValueError(f"time {t!r}")
            with contextlib.redirect_stderr(said):
                a = parser().parse_args(["-c", "-"] + text.split())
            build(a)
            commands.append((tt, text))
        except (ValueError, SystemExit) as e:
            lines = said.getvalue().strip().splitlines()
            why = lines[-1].split("error: ", 1)[-1] if lines else str(e)
            return bad(f"--do {show(repr(item))}: expected T:COMMAND with a valid command ({why})")
    held = held_capture(Path(args.out))
    if held and not args.overwrite:
        rows, files = held
        what = f"{rows} samples" if rows > 0 else "a capture"
        return bad(
            f"--out {show(args.out)} holds {what} ({', '.join(p.suffix for p in files)}): nothing was changed; "
            "choose another name, or --overwrite to replace it"
        )
    problem = check_out(Path(args.out), formats)
    if problem:
        return bad(problem)
    if held:
        for p in held[1] + [Path(args.out).with_name(Path(args.out).name + ".npz.tmp")]:
            p.unlink(missing_ok=True)
        print(
            f"logger: --overwrite: removed the capture {show(args.out)} ({', '.join(p.suffix for p in held[1])})",
            file=sys.stderr,
        )
    log = RigLogger(
        args.interface,
        args.channel,
        Path(args.out),
        formats,
        args.bitrate,
        give_up_s=args.give_up,
        first_frame_s=args.first_frame,
        wait_open_s=args.wait_open,
        source=args.source,
        n_cells=n_cells,
        topology=topology,
    )
    log.commands = sorted(commands)
    try:
        n = log.run(args.duration)
    except RunFailed as e:
        print(f"logger: {e}", file=sys.stderr)
        return 3
    arr = log.arrays
    per_cell = np.sum(~np.isnan(arr["alpha_counts"]), axis=0)
    lost = int(arr["gaps"][:, 3].sum()) if len(arr["gaps"]) else 0
    why = f"; stopped by {log.stop_reason}" if log.stop_reason else ""
    print(
        f"{n} frames; samples per cell min {per_cell.min() if len(per_cell) else 0} max "
        f"{per_cell.max() if len(per_cell) else 0}; {len(arr['gaps'])} gaps ({lost} samples lost); "
        f"{log.reconnects} reconnects; {log.corrupt} corrupt lines; "
        + (f"{len(log.others)} other program(s) read the port too; " if log.others else "")
        + f"wrote {args.out}.npz/.csv and "
        f"{','.join(formats)}{why}"
    )
    return 0
