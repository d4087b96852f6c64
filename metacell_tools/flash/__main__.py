"""CLI: python -m metacell_tools.flash inventory|plan|flash|identify (see docs/hardware.md)."""

from __future__ import annotations

import argparse
import functools
import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

from . import emulated
from . import inventory as inv
from .addresses import CELL_COUNT, MAX_CELL_COUNT, cell_address
from .boards import Port, PortListError, port_lister, xiao_ports
from .identity import IdentityError, QueryResult, expected_fw_version, query_identity
from .plan import ROOT, PlanError, describe, make_plan, parse_only, with_prebuilt, with_toolchain
from .runner import Flasher, summary
from .toolchain import APP_OFFSET, UPLOADERS, PreflightError, check_offset, find_toolchain

Lister = Callable[[], list[Port]]  # lists the connected serial ports
Out = Callable[..., None]  # prints one line for the user (err=True: an error)

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
REAPPEAR_S, BOOTLOADER_S = 20.0, 10.0  # the timeouts' defaults (--emulated: emulated.py's)
RETRIES = 1  # a failed bossac is run again once (--retries)


def default_pio() -> str:
    if os.environ.get("MC_PIO"):
        return os.environ["MC_PIO"]
    found = shutil.which("pio")
    if found:
        return found
    sibling = Path(sys.executable).with_name("pio")
    return str(sibling) if sibling.exists() else "pio"


def _address(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an address (0x2000, 8192)") from None


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.flash",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.flash inventory --assign 1 --serial <USB serial>   # once per board\n"
        "  python -m metacell_tools.flash plan                                         # what flash would do\n"
        "  python -m metacell_tools.flash flash --only 1-4,primary\n"
        "  python -m metacell_tools.flash flash --keep-going                          # go on past a failed board\n"
        "  python -m metacell_tools.flash identify\n"
        "  python -m metacell_tools.flash SUBCOMMAND --help",
    )
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--inventory", default=str(inv.DEFAULT_PATH), help="board inventory JSON (default: %(default)s)"
    )
    common.add_argument(
        "--ports-json", metavar="FILE", help="use this JSON list of ports instead of the USB ports (no hardware)"
    )
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="SUBCOMMAND", help="what to do")

    p = sub.add_parser(
        "inventory",
        parents=[common],
        help="show connected boards; --assign one to a cell or the primary",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  python -m metacell_tools.flash inventory\n"
        "  python -m metacell_tools.flash inventory --assign primary --serial 8A1B2C3D\n"
        "  python -m metacell_tools.flash inventory --assign 5 --replace       # a new board in slot 5\n"
        "  python -m metacell_tools.flash inventory --cells 64                # a sheet of 64 cells + primary",
    )
    p.add_argument("--assign", metavar="N|primary", help="record a board as cell N or the primary")
    p.add_argument(
        "--cells",
        type=int,
        metavar="N",
        help=f"the rig's cell count, 1..{MAX_CELL_COUNT} (default {CELL_COUNT}, the rig as built): cells "
        "1..N answer at 0x10..0x10+N-1 and the primary is built to poll N",
    )
    p.add_argument("--serial", help="which board to assign (default: the only unassigned one connected)")
    p.add_argument("--replace", action="store_true", help="take the slot from the board holding it")

    for name, helptext, examples in (
        ("plan", "print what flash would do, touching nothing", ("plan", "plan --only 1-4,primary")),
        (
            "flash",
            "build, upload and verify every board (stops at the first failure)",
            ("flash", "flash --only 7", "flash --keep-going --uploader bossac", "flash --emulated   # the dry run"),
        ),
    ):
        p = sub.add_parser(
            name,
            parents=[common],
            help=helptext,
            formatter_class=argparse.RawDescriptionHelpFormatter,
            epilog="examples:\n" + "\n".join(f"  python -m metacell_tools.flash {e}" for e in examples),
        )
        p.add_argument("--only", help="boards to include, e.g. '1-4,7,primary' (default: all)")
        p.add_argument(
            "--skip-missing",
            action="store_true",
            help="flash the connected boards even if some inventory boards are absent",
        )
        p.add_argument("--pio", default=None, help="PlatformIO executable (default: $MC_PIO, pio on PATH, .venv's)")
        p.add_argument("--project", default=str(ROOT), help="PlatformIO project dir")
        p.add_argument(
            "--uploader",
            choices=UPLOADERS,
            default="auto",
            help="PlatformIO's own uploader (its tool-bossac package), or bossac after a 1200-baud touch; auto: "
            "PlatformIO's when installed, else bossac (default %(default)s)",
        )
        p.add_argument("--bossac", default=None, help="the bossac executable (default: $MC_BOSSAC, bossac on PATH)")
        p.add_argument(
            "--offset",
            type=_address,
            default=APP_OFFSET,
            metavar="ADDR",
            help=f"where bossac writes the application (default 0x{APP_OFFSET:x}, above the bootloader; lower is "
            "refused)",
        )
        p.add_argument(
            "--overwrite-bootloader",
            action="store_true",
            help="let --offset go below 0x2000: the bootloader is overwritten and the board never comes back over "
            "USB (only an SWD probe restores it)",
        )
        if name == "flash":
            go_on = p.add_mutually_exclusive_group()
            go_on.add_argument(
                "--keep-going",
                action="store_true",
                help="go on with the other boards after a failed one (default: stop at the first failure)",
            )
            go_on.add_argument(
                "--stop-on-error",
                action="store_true",
                help="stop at the first failed board (the default; kept for old scripts)",
            )
            p.add_argument(
                "--log-dir",
                default=str(Path(".pio") / "flash-logs"),
                help="directory for each board's build and upload output (default: %(default)s)",
            )
            p.add_argument(
                "--upload-timeout",
                type=float,
                default=600.0,
                metavar="S",
                help="seconds one board's build and upload may take (default %(default)g)",
            )
            p.add_argument(
                "--retries",
                type=int,
                default=None,
                metavar="N",
                help="run a failed bossac again up to N times while its board stays in its bootloader (default "
                f"{RETRIES})",
            )
            p.add_argument(
                "--reappear-timeout",
                type=float,
                default=None,
                metavar="S",
                help=f"seconds to wait for a board's USB port to come back after the upload (default {REAPPEAR_S:g}; "
                f"--emulated: {emulated.REAPPEAR_TIMEOUT_S:g})",
            )
            p.add_argument(
                "--jobs",
                type=int,
                default=None,
                metavar="N",
                help="flash N boards at once (bossac: each board its own port and bossac; default 1, with --emulated "
                "every board)",
            )
            p.add_argument(
                "--emulated",
                action="store_true",
                help="the rig day as a dry run: bring up 17 blank emulated boards (python -m host_emulator boards "
                "--blank; needs MC_BOOTLOADER), flash and verify them with bossac, stop them (generous timeouts)",
            )
            p.add_argument(
                "--emulated-count",
                type=int,
                default=17,
                metavar="N",
                help="--emulated: the first N boards of cells 1..16, primary (default %(default)s)",
            )
            p.add_argument(
                "--emulated-arg",
                action="append",
                default=[],
                metavar="ARG",
                help="--emulated: an argument for the boards (python -m host_emulator boards), e.g. "
                "--emulated-arg=--set=model_options.image.threads=2 or --emulated-arg=--usb-packet-us=50",
            )
            p.add_argument(
                "--bossac-clock-rate",
                type=float,
                default=None,
                metavar="R",
                help="run bossac with its clock at R of real time (faketime), so that its fixed waits for an answer "
                "(0.1 s to 5 s) stretch to the pace of boards emulated slower than real time (default 1: its own "
                f"clock; --emulated: {emulated.BOSSAC_CLOCK_RATE:g})",
            )
            p.add_argument(
                "--emulated-control",
                default=None,
                metavar="DIR",
                help="--emulated: the boards' control directory (boards --control: unplug-TAG[-at-N], deaf-TAG); "
                "every board's flash is read back into it (flash-TAG.bin) before they stop",
            )
            p.add_argument(
                "--prebuilt",
                default=None,
                metavar="DIR",
                help="upload DIR/cellNN/firmware.elf and DIR/primary/firmware.elf (bossac) instead of building "
                "(the emulator's image cache holds these builds)",
            )
            p.add_argument(
                "--bootloader-timeout",
                type=float,
                default=None,
                metavar="S",
                help=f"seconds to wait for a board's bootloader port after the 1200-baud touch (bossac; default "
                f"{BOOTLOADER_S:g}; --emulated: {emulated.BOOTLOADER_TIMEOUT_S:g})",
            )

    sub.add_parser(
        "identify",
        parents=[common],
        help="ask every connected XIAO for its identity; flag duplicate addresses",
        epilog="example: python -m metacell_tools.flash identify",
    )
    return ap


def cmd_inventory(args: argparse.Namespace, lister: Lister, out: Out) -> int:
    path = Path(args.inventory)
    boards, cells = inv.read(path) if path.exists() else ([], CELL_COUNT)
    ports = xiao_ports(lister())
    by_serial = {b.serial: b for b in boards}
    if args.cells is not None and args.cells != cells:
        cells = inv.check_cells(args.cells)
        beyond = [b.name for b in boards if b.role == "cell" and b.cell is not None and b.cell > cells]
        if beyond:
            raise inv.InventoryError(f"--cells {cells}: the inventory still has {', '.join(beyond)} (reassign them)")
        if not args.assign:
            inv.save(path, boards, cells)
            span = f"0x{cell_address(1):02x}..0x{cell_address(cells):02x}"
            out(f"{path}: the rig has {cells} cells (addresses {span}) + primary")
    if args.assign:
        if args.serial:
            serial = args.serial
        else:
            free = [p for p in ports if p.serial_number and p.serial_number not in by_serial]
            if len(free) != 1:
                out(
                    f"error: {len(free)} unassigned XIAO boards connected; connect exactly one "
                    f"new board or name it with --serial",
                    err=True,
                )
                return EXIT_USAGE
            serial = free[0].serial_number
        boards = inv.assign(boards, serial, args.assign, replace=args.replace, cells=cells)
        inv.save(path, boards, cells)
        out(f"{path}: serial {serial} is now {next(b for b in boards if b.serial == serial).name}")
        by_serial = {b.serial: b for b in boards}
    out(f"connected XIAO boards ({len(ports)}):")
    for p in ports:
        b = by_serial.get(p.serial_number) if p.serial_number else None
        mode = " [bootloader]" if p.in_bootloader else ""
        out(f"  {p.device:16s} serial {p.serial_number}{mode}: {b.name if b else 'UNASSIGNED'}")
    present = {p.serial_number for p in ports}
    for b in boards:
        if b.serial not in present:
            out(f"  (not connected) {b.name} serial {b.serial}")
    return EXIT_OK


def cmd_plan_or_flash(args: argparse.Namespace, lister: Lister, out: Out) -> int:
    """The plan (boards, ports), then whether this machine can build and upload (PreflightError), all before any board
    is touched; then flash: stop at the first failure unless --keep-going. --emulated: on blank emulated boards."""
    bad_offset = check_offset(args.offset, args.overwrite_bootloader)
    if bad_offset:
        raise PreflightError(bad_offset)
    if (getattr(args, "jobs", None) or 1) < 1:
        raise PreflightError(f"--jobs must be at least 1, got {args.jobs}")
    if getattr(args, "retries", None) is not None and not 0 <= args.retries <= 10:
        raise PreflightError(f"--retries must be 0..10, got {args.retries}")
    if getattr(args, "emulated", False):
        return _flash_emulated(args, out)
    if not hasattr(args, "bossac_env"):
        args.bossac_env = bossac_env(args)
    boards, cells = inv.read(args.inventory)
    pio = args.pio or default_pio()
    project = Path(args.project)
    plan = make_plan(
        boards,
        lister(),
        pio=pio,
        project=project,
        only=parse_only(args.only, cells),
        skip_missing=args.skip_missing,
        cells=cells,
    )
    prebuilt = getattr(args, "prebuilt", None)
    if prebuilt:
        tools = find_toolchain(pio, project, uploader="bossac", bossac=args.bossac, offset=args.offset, build=False)
        plan = with_prebuilt(plan, tools, Path(prebuilt))
    else:
        tools = find_toolchain(pio, project, uploader=args.uploader, bossac=args.bossac, offset=args.offset)
        plan = with_toolchain(plan, tools, project)
    out(describe(plan))
    out(tools.describe() if not prebuilt else f"prebuilt images from {prebuilt}; upload: {tools.describe_upload()}")
    if args.cmd == "plan":
        return EXIT_OK
    slow: dict = {}  # emulated boards: ID? may wait longer, the uploads start together (runner.Gate)
    if getattr(args, "emulated_query_timeout", None):
        slow["query"] = functools.partial(query_identity, timeout=args.emulated_query_timeout)
        slow["together_s"] = emulated.TOGETHER_S
    flasher = Flasher(
        lister,
        **slow,
        expected_fw=expected_fw_version(),
        log_dir=args.log_dir,
        upload_timeout=args.upload_timeout,
        reappear_timeout=REAPPEAR_S if args.reappear_timeout is None else args.reappear_timeout,
        bootloader_timeout=BOOTLOADER_S if args.bootloader_timeout is None else args.bootloader_timeout,
        retries=RETRIES if getattr(args, "retries", None) is None else args.retries,
        bossac_env=getattr(args, "bossac_env", {}),
        out=out,
    )
    outcomes = flasher.flash(plan, stop_on_error=not args.keep_going, jobs=args.jobs or 1)
    out(summary(outcomes))
    for b in plan.missing:
        out(f"NOT FLASHED (not connected): {b.name} serial {b.serial}")
    out("check the whole bus with: python -m metacell_tools.flash identify")
    return EXIT_OK if all(o.ok for o in outcomes) and not plan.missing else EXIT_FAILED


def bossac_env(args: argparse.Namespace) -> dict[str, str]:
    """What bossac's environment gains (--bossac-clock-rate; --emulated's default), or PreflightError in one line."""
    rate = getattr(args, "bossac_clock_rate", None)
    if rate is None:
        rate = emulated.BOSSAC_CLOCK_RATE if getattr(args, "emulated", False) else 1.0
    if not 0.001 <= rate <= 1:
        raise PreflightError(f"--bossac-clock-rate must be 0.001..1, got {rate:g}")
    try:
        return emulated.bossac_env(rate)
    except emulated.EmulationError as exc:
        raise PreflightError(str(exc)) from None


def _flash_emulated(args: argparse.Namespace, out: Out) -> int:
    """flash --emulated: the same preflight (plus MC_BOOTLOADER), then the plan on blank emulated boards, which are
    stopped at the end; the timeouts given on the command line are raised to the emulation's where lower."""
    missing = emulated.preflight()
    pio = args.pio or default_pio()
    if args.prebuilt:
        find_toolchain(pio, Path(args.project), uploader="bossac", bossac=args.bossac, offset=args.offset, build=False)
    else:
        find_toolchain(pio, Path(args.project), uploader="bossac", bossac=args.bossac, offset=args.offset)
    if missing:
        raise PreflightError(missing)
    if not 1 <= args.emulated_count <= emulated.N_BOARDS:
        raise PreflightError(f"--emulated-count must be 1..{emulated.N_BOARDS}")
    clock = bossac_env(args)
    try:
        with emulated.emulated_boards(
            ROOT,
            args.emulated_count,
            control=Path(args.emulated_control) if args.emulated_control else None,
            extra=tuple(args.emulated_arg),
            out=out,
        ) as (listing, inventory):
            emu = argparse.Namespace(**vars(args))
            emu.emulated, emu.uploader, emu.ports_json, emu.inventory = False, "bossac", str(listing), str(inventory)
            if args.bootloader_timeout is None:
                emu.bootloader_timeout = emulated.BOOTLOADER_TIMEOUT_S
            if args.reappear_timeout is None:
                emu.reappear_timeout = emulated.REAPPEAR_TIMEOUT_S
            emu.emulated_query_timeout = emulated.IDENTITY_TIMEOUT_S
            emu.jobs = args.jobs or args.emulated_count
            emu.bossac_env = clock  # (checked before the boards are brought up)
            return cmd_plan_or_flash(emu, port_lister(listing), out)
    except emulated.EmulationError as exc:
        out(f"error: {exc}", err=True)
        return EXIT_FAILED


def cmd_identify(
    args: argparse.Namespace, lister: Lister, out: Out, query: Callable[[str], QueryResult] = query_identity
) -> int:
    path = Path(args.inventory)
    by_serial = {b.serial: b for b in inv.load(path)} if path.exists() else {}
    claims: dict[int, list[str]] = {}
    problems = 0
    for p in xiao_ports(lister()):
        if p.in_bootloader:
            out(f"  {p.device:16s} serial {p.serial_number}: in bootloader (no firmware running)")
            problems += 1
            continue
        try:
            q = query(p.device)
        except (IdentityError, OSError) as exc:
            out(f"  {p.device:16s} serial {p.serial_number}: ERROR {exc}")
            problems += 1
            continue
        b = by_serial.get(p.serial_number) if p.serial_number else None
        if q.identity is None:
            out(f"  {p.device:16s} serial {p.serial_number}: no answer to ID?")
            problems += 1
            continue
        note = ""
        if b is not None and (b.role, b.cell, b.addr) != (q.identity.role, q.identity.cell, q.identity.addr):
            note = f"  MISMATCH: inventory says {b.name}"
            problems += 1
        if q.errors:
            note += f"  start-up error: {', '.join(q.errors)}"
            problems += 1
        out(f"  {p.device:16s} serial {p.serial_number}: {q.identity.describe()}{note}")
        if q.identity.addr is not None:
            claims.setdefault(q.identity.addr, []).append(f"{p.device} (serial {p.serial_number})")
    for addr, who in sorted(claims.items()):
        if len(who) > 1:
            out(f"error: two boards claim address 0x{addr:02x}: {', '.join(who)}", err=True)
            problems += 1
    return EXIT_OK if problems == 0 else EXIT_FAILED


def main(argv: list[str] | None = None, out: Out | None = None) -> int:
    def _out(msg, err=False):
        print(msg, file=sys.stderr if err else sys.stdout)

    out = out or _out
    args = _parser().parse_args(argv)
    try:
        lister = port_lister(args.ports_json)
        if args.cmd == "inventory":
            return cmd_inventory(args, lister, out)
        if args.cmd in ("plan", "flash"):
            return cmd_plan_or_flash(args, lister, out)
        return cmd_identify(args, lister, out)
    except (inv.InventoryError, PlanError, PortListError, PreflightError) as exc:
        out(f"error: {exc}", err=True)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
