"""`python -m host_emulator serve [SCENE] --slcan`: run a hil scene paced to real time, the emulated primary
speaking SLCAN on a pty.

The first output line is ``slcan pty: <path>``; point python-can at it with
``-i slcan -c <path>@115200``. Runs until interrupted (or --duration seconds).

Sessions: a client's open and close of the pty are the emulated USB port's open and
close (DTR): at each, the primary starts a new session (mc_link_session: channel
closed, queued frames and any half line dropped) and the unread output is discarded,
so a client that died without ``C`` leaves nothing stale for the next one.

--wait-client holds the scene at t = 0 (nothing runs) until a client opens the port and its CAN channel (SLCAN O
or L), then starts it: a capture (python -m can.logger, the rig logger) begins with the scene, its pushes included.

Back-pressure: a rig that cannot take a client's bytes yet (the image tier's emulated USB host, whose buffer the
primary drains at its own pace) holds them and says so (``ready()``); serve then stops reading the pty until it
can, so a client writing faster than the primary reads blocks in its write and nothing it sent is lost.

One reader per port: a pty read by two programs gives each part of the bytes. While a client holds the pty,
serve looks every second at which processes hold it (/proc, as the tools' portlock does); a second program is
reported on stderr when it appears and counted (``second-client events`` in the final line).
Exit codes: 0 ok, 2 bad arguments, 3 the run failed.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import select
import signal
import sys
import time
import tty

from metacell_common.portlock import holders

from ..limits import check_realtime, check_run, check_solver
from ..models.plant import NumericalInstability
from ..outpaths import show
from .rig import BusOptions, make_rig

CHUNK_S = 0.005  # simulated time advanced per loop pass
BACKLOG_MAX = 1 << 16  # bytes kept for a slow reader before new output is dropped


def _cells(text: str) -> tuple:
    if not text:
        return ()
    try:
        cells: tuple[int, ...] = ()
        for part in (p.strip() for p in text.split(",")):
            lo, sep, hi = part.partition("-")  # "3-5" is cells 3, 4, 5
            a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
            cells += tuple(range(a, b + 1))
        if not cells:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected cell numbers or ranges like 3,7 or 1-4, got {text!r}") from None
    for j in cells:
        if not 1 <= j <= 16:
            raise argparse.ArgumentTypeError(f"cell {j} outside 1..16")
    return cells


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator serve",
        description="Serve the emulated rig's primary as an SLCAN device on a pseudo-terminal.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator serve default --slcan              # prints 'slcan pty: /dev/pts/N'\n"
        "  python -m host_emulator serve exp1_ccw_ccw --slcan --link /tmp/rig --absent 3,7\n"
        "  python -m metacell_tools.rigtools.logger -c /dev/pts/N@115200 --out out/log   # in another shell\n"
        "  python -m host_emulator serve default --slcan --wait-client   # the scene starts when the client opens it",
    )
    ap.add_argument(
        "scene", nargs="?", default="default", help="hil or image scene name or .toml path (default: default)"
    )
    ap.add_argument("--slcan", action="store_true", help="speak SLCAN on a pty (the only mode; accepted for clarity)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override, as for run")
    ap.add_argument(
        "--i2c-hz",
        type=int,
        default=400_000,
        choices=(100_000, 400_000),
        help="I2C clock of the emulated bus, Hz (default 400000)",
    )
    ap.add_argument("--period-us", type=int, default=0, help="poll cycle period (0: as fast as the bus allows)")
    ap.add_argument("--duration", type=float, default=None, help="stop after this many seconds (default: run on)")
    ap.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall second (default 1)")
    ap.add_argument("--link", default=None, help="also create this symlink to the pty")
    ap.add_argument("--absent", type=_cells, default=(), help="cells that never answer (e.g. 3,7)")
    ap.add_argument("--stuck", type=_cells, default=(), help="cells that hold the bus until the timeout")
    ap.add_argument("--babble", type=_cells, default=(), help="cells that answer random bytes")
    ap.add_argument(
        "--wait-client",
        action="store_true",
        help="hold the scene at t = 0 until a client opens the port and its CAN channel (SLCAN O or L): a capture "
        "(python -m can.logger) then holds the scene from its start, the scene's pushes included",
    )
    return ap


def open_pty() -> tuple[int, int, str]:
    """(master fd, slave fd, slave path) of a raw pty. The caller closes the slave: with no
    client holding it, reads of the master fail with EIO, which is how a client's close is seen."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def check_args(args: argparse.Namespace) -> str | None:
    """The first problem with the numeric arguments, or None."""
    if not (math.isfinite(args.speed) and 1e-3 <= args.speed <= 1e3):
        return f"--speed must be a finite number in 0.001..1000, got {args.speed}"
    if args.duration is not None and not (math.isfinite(args.duration) and 0 < args.duration <= 1e7):
        return f"--duration must be a finite number of seconds in (0, 1e7], got {args.duration}"
    if not 0 <= args.period_us <= 10_000_000:
        return f"--period-us must be in 0..10000000 (the primary's range), got {args.period_us}"
    return None


def check_link(link: str) -> str | None:
    """--link must name a symlink we may create (an existing symlink is replaced, nothing else): why not, or None."""
    try:
        if os.path.lexists(link) and not os.path.islink(link):
            return f"--link {show(link)}: exists and is not a symlink (not replaced)"
        parent = os.path.dirname(link) or "."
        os.makedirs(parent, exist_ok=True)
        probe = os.path.join(parent, f".link-probe-{os.getpid()}")
        os.symlink(os.devnull, probe)
        os.unlink(probe)
        if not os.path.islink(link):  # the name itself (its length) is checked by making it
            os.symlink(os.devnull, link)
            os.unlink(link)
    except OSError as e:
        return f"--link {show(link)}: cannot create it: {e.strerror or e}"
    return None


def opens_channel(pending: bytearray, data: bytes) -> bool:
    """Whether the client's bytes (appended to `pending`, the part of a line not yet ended) hold an SLCAN command
    that opens the CAN channel (O, or L: listen only); the ended lines are dropped from `pending`."""
    pending += data
    *lines, rest = bytes(pending).split(b"\r")
    pending[:] = rest[-64:]
    return any(line.strip() in (b"O", b"L") for line in lines)


class ClientWatch:
    """Counts the programs holding the served pty (portlock.holders, at most once per second): more than one means
    the readers split the bytes between them; each such appearance is one event, said once on stderr."""

    EVERY_S = 1.0

    def __init__(self, path: str) -> None:
        self.path = path
        self.events = 0
        self.most = 0
        self.next = 0.0
        self.seen: frozenset[int] = frozenset()

    def poll(self) -> None:
        now = time.monotonic()
        if now < self.next:
            return
        self.next = now + self.EVERY_S
        held = holders(self.path, exclude={os.getpid()})
        self.most = max(self.most, len(held))
        pids = frozenset(held)
        if len(pids) > 1 and not pids <= self.seen:
            self.events += 1
            who = "; ".join(f"pid {p}: {c}" for p, c in sorted(held.items()))
            print(
                f"serve: {len(pids)} programs hold {self.path} ({who}): each reads part of the frames "
                "(one reader per port)",
                file=sys.stderr,
                flush=True,
            )
        self.seen = pids if len(pids) > 1 else frozenset()


def serve_main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    problem = check_args(args)
    if problem:
        print(f"serve: {problem}", file=sys.stderr)
        return 2
    try:
        rig, scene = make_rig(
            args.scene,
            BusOptions(
                i2c_hz=args.i2c_hz, period_us=args.period_us, absent=args.absent, stuck=args.stuck, babble=args.babble
            ),
            args.set,
        )
    except (ValueError, KeyError, OSError) as e:
        print(f"serve: {e}", file=sys.stderr)
        return 2
    problem = check_run(scene) or check_solver(scene, rig.solver) or check_realtime(scene, rig.solver, args.speed)
    if problem:
        print(f"serve: {problem}", file=sys.stderr)
        return 2
    if args.link:
        problem = check_link(args.link)
        if problem:
            print(f"serve: {problem}", file=sys.stderr)
            return 2
    master, slave, path = open_pty()
    os.close(slave)
    client = False  # a client holds the pty open (reads of the master do not fail with EIO)
    sessions = 0
    if args.link:
        try:
            if os.path.islink(args.link):
                os.unlink(args.link)
            os.symlink(path, args.link)
        except OSError as e:
            os.close(master)
            print(f"serve: --link {args.link[:80]}: cannot create it: {e.strerror or e}", file=sys.stderr)
            return 2
    watch = ClientWatch(path)
    print(f"slcan pty: {path}  (python -m can.logger -i slcan -c {path}@115200)", flush=True)
    # the model first: a scene file's description names the model it was written for, not the one --set chose
    print(
        f"scene {scene.name}: model {scene.model}, I2C {args.i2c_hz} Hz, {rig.n} cells (the scene file says: "
        f"{scene.description})",
        flush=True,
    )
    started = not args.wait_client  # the scene's clock runs (--wait-client: from the client's channel open)
    if not started:
        print("waiting for a client: the scene starts when it opens the CAN channel (--wait-client)", flush=True)
    line: bytearray = bytearray()  # --wait-client: the client's unfinished SLCAN line
    status = 0
    stop = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    signal.signal(signal.SIGHUP, lambda *a: stop.append(1))
    backlog = bytearray()
    dropped = 0
    ready = getattr(rig, "ready", None)  # the image tier: False while it holds input the emulated USB cannot take
    hangup = select.poll()  # POLLHUP on the master: no client holds the pty (seen without reading it)
    hangup.register(master, 0)
    t0 = time.monotonic()
    sim_us = 0
    try:
        while not stop:
            if args.duration is not None and sim_us >= args.duration * 1e6:
                break
            if started:
                sim_us += int(CHUNK_S * 1e6)
                rig.advance_to(sim_us)
            if ready is None or ready():
                try:
                    data = os.read(master, 4096)
                    present = True
                except OSError as e:
                    if e.errno not in (errno.EAGAIN, errno.EIO):
                        raise
                    data = b""
                    present = e.errno == errno.EAGAIN
            else:  # back-pressure: the rig holds bytes it could not pass on; the client's stay in the pty meanwhile
                data = b""
                present = not hangup.poll(0)
            if present != client:  # a client opened or closed the port: new session
                client = present
                sessions += present
                rig.session()
                backlog.clear()
                line.clear()
            if client:
                watch.poll()
            if data:
                backlog += rig.feed(data)
                if not started and opens_channel(line, data):
                    started = True
                    t0 = time.monotonic()
                    print(f"client opened the CAN channel (session {sessions}): scene started", flush=True)
            out = rig.drain()
            if len(backlog) + len(out) > BACKLOG_MAX:
                dropped += len(out)  # nobody reads: drop new output (gaps show in seq)
            else:
                backlog += out
            if backlog and client:
                try:
                    n = os.write(master, backlog)
                    del backlog[:n]
                except OSError as e:
                    if e.errno not in (errno.EAGAIN, errno.EIO):
                        raise
            lag = sim_us / 1e6 / args.speed - (time.monotonic() - t0) if started else CHUNK_S
            if lag > 0:
                time.sleep(lag)
    except KeyboardInterrupt:
        pass
    except NumericalInstability as e:
        print(f"serve: stopped at t = {sim_us / 1e6:.3f} s: {e}", file=sys.stderr, flush=True)
        status = 3
    finally:
        if args.link:
            try:
                os.unlink(args.link)
            except OSError:
                pass
        os.close(master)
    if hasattr(rig, "summary"):  # the image tier: the flashed primary's counters stay in its own RAM
        print(
            f"served {sim_us / 1e6:.1f} s: {rig.summary(sim_us / 1e6, time.monotonic() - t0)}, {sessions} client "
            f"sessions, {dropped} bytes dropped (slow reader), {watch.events} second-client events (most programs "
            f"on the pty at once: {watch.most})",
            flush=True,
        )
        return status
    p = rig.p
    print(
        f"served {sim_us / 1e6:.1f} s: {p.cycles} poll cycles, {rig.transactions} transactions, "
        f"{sessions} client sessions, {dropped} bytes dropped (slow reader), {p.tx_drop} frames dropped "
        f"(queue full), {p.no_room} commands answered NO_ROOM, {p.ans_drop} answers dropped, "
        f"{rig.band_stops} plant range stops reported as runaway faults, "
        f"{watch.events} second-client events (most programs on the pty at once: {watch.most})",
        flush=True,
    )
    return status


if __name__ == "__main__":
    raise SystemExit(serve_main())
