"""`python -m host_emulator boards`: emulated boards as a laptop sees them: each image's USB port a pty, a port listing.

Brings up N boards of the image tier (17 by default: cells 1..16 with their per-address images, then the primary;
--count takes the first N of that list) and runs until interrupted. Each board's USB CDC port is a pty reachable
under a stable name containing ttyACM (<dev-dir>/ttyACM-mc01 ... ttyACM-mc16, ttyACM-primary), and the ports are
listed in PATH (--ports-json) as `python -m metacell_tools.flash ... --ports-json PATH` reads them (VID:PID, serial
number, manufacturer, product: what each board's own descriptors said when the tier's USB host enumerated it as Linux
does; the device, description, and the board's mode), rewritten atomically whenever a board enumerates or goes.

The USB host behaves as Linux's cdc_acm on each port: a client's open raises DTR and RTS, its speed (tcsetattr) is
sent as the line coding, its close drops DTR and RTS. A 1200-baud touch of a port (speed set to 1200, then the port
closed) resets the board. With MC_BOOTLOADER (the XIAO bootloader's .bin) the boards boot through it and the touch
reaches the firmware as it would on a laptop (Seeed's core erases the application's first row and resets: the board
comes back in bootloader mode with the bootloader's PID, where bossac writes the flash through SAM-BA; --blank brings
up boards holding the bootloader alone, as new XIAOs arrive); without it the tier says so in one line, resets the
board from outside and the application restarts directly, enumerating again with the application's PID. Either way
the port is made again as the operating system makes it when a device re-enumerates: a new pty behind the same
stable name, the listing updated. --control DIR takes requests as files (unplug a board, make it ignore the touch,
read every board's flash back). The boards' time runs as fast as it can but never ahead of real time. The mechanical
plant is at rest unless --plant: then it starts (scene time 0, as `run --set model=image` starts it after bring-up)
once every board is up running its application (after --blank boards were flashed), and the cells' motors and
encoders move as on the rig; the scene's configuration is the client's to send (the experiment runner through the
primary).
Exit codes: 0 interrupted (ptys and listing removed), 2 bad arguments or the tier cannot run, 3 the run failed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import select
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from metacell_common.target.board import XIAO_PID_APP, XIAO_PID_BOOT

from .ptyport import PtyPort

if TYPE_CHECKING:
    from .world import UsbDevice

N_BOARDS = 17  # cells 1..16, then the primary
CHUNK_S = 0.002  # world time run between two looks at the ports
# while a client talks to a bootloader: bossac gives many answers 100 ms of wall time (its quick timeout), and
# each SAM-BA command takes a few looks at the ports to go and come back
CHUNK_BUSY_S = 0.25e-3
WAIT_MAX_S = 0.02  # longest sleep while the world is ahead of real time (a new client is seen within it)
LAG_MAX_S = 0.1  # a world behind real time by more does not sprint to catch up later
APPLICATION, BOOTLOADER = "application", "bootloader"
MODES = {XIAO_PID_APP: APPLICATION, XIAO_PID_BOOT: BOOTLOADER}  # idProduct -> mode
TOUCH_BAUD = 1200
FLASH_SIZE = 0x40000  # the SAMD21G18's 256 KiB
CONTROL_EVERY_S = 0.1  # wall time between two looks at the control directory


def say(msg: str) -> None:
    print(f"boards: {msg}", file=sys.stderr, flush=True)


def bootloader_problem(lib=None) -> str | None:
    """Why a board cannot run the XIAO's bootloader here (one line), or None when it can: MC_BOOTLOADER names the
    pinned bootloader's .bin (the tier runs it from the reset vector, image/bootloader.py). `lib` is unused (kept for
    callers that pass the runtime)."""
    from . import bootloader

    if bootloader.path() is None:
        return "MC_BOOTLOADER (the path of the XIAO bootloader's .bin) is not set"
    try:
        bootloader.load()
    except bootloader.BootloaderError as e:
        return str(e)
    return None


PACKET = 64  # the XIAO's bulk endpoints' wMaxPacketSize
SAMBA_WRITE = re.compile(rb"[Ss]([0-9A-Fa-f]{1,8}),([0-9A-Fa-f]{1,8})#$")


class SambaFramer:
    """Where the client's write() calls ended, for a port in bootloader mode. On Linux each write() to a CDC ACM port
    is its own USB transfer (cdc_acm submits one URB per write), and the bootloader's SAM-BA monitor relies on it:
    bossac writes a command ("S20004034,00001000#") and then its data in two calls, and the monitor drops whatever
    follows a command in the same packet. A pty merges the writes, so they are split again where bossac's calls
    ended: after each command's '#', and after the `size` bytes of data an S command announces."""

    def __init__(self) -> None:
        self.data_left = 0
        self.mid_data = False  # part of an S command's data went: the rest continues the same write()

    def continues(self) -> bool:
        """The next bytes continue the transfer under way (no need to wait until the device took it)."""
        return self.mid_data and self.data_left > 0

    def transfer(self, held: bytes | bytearray) -> int:
        """How many of the held bytes make the next transfer (each is given to the device once the last one went;
        0: wait for more). Data goes in whole packets until its last one, as cdc_acm sends a write (its buffers are
        20 packets long): a short packet inside an S command's data would end the monitor's read of it early."""
        if self.data_left:
            n = min(len(held), self.data_left)
            if n < self.data_left:
                n -= n % PACKET
            self.data_left -= n
            self.mid_data = self.data_left > 0
            return n
        end = bytes(held).find(b"#")
        if end < 0:
            return len(held) if len(held) >= PACKET else 0  # a command not finished yet (or not SAM-BA at all)
        m = SAMBA_WRITE.search(bytes(held[: end + 1]))
        if m is not None:
            self.data_left = int(m.group(2), 16)
        return end + 1


@dataclass
class Board:
    """One emulated board as the laptop sees it: its world index, stable name, serial number, mode and port."""

    k: int  # 0..16 in the order cells 1..16, primary
    index: int  # the World's board index
    name: str  # "cell 1" | "primary"
    link: str  # the stable name
    serial: str  # the iSerialNumber string the board sent (its place's fallback until it enumerated)
    mode: str = ""  # APPLICATION | BOOTLOADER when enumerated; "" while it is not (not listed)
    port: PtyPort | None = None
    resets: int = 0
    comes_back_as: str = APPLICATION  # what the next enumeration is (the reset hook chose)
    enumerations: int = 0
    resetting: bool = False  # a reset was asked for and has not happened yet
    held: bytearray = field(default_factory=bytearray)  # the client's bytes not yet given to the USB host
    line_state_at: int = 0  # control transfers started when the client's open has reached the board
    device: UsbDevice | None = None  # World.usb_device at its last enumeration: what the board said (VID, PID, strings)
    enumerations_seen: int = 0  # the host's count of the board's enumerations when its port was made
    line: tuple[int, bool] = (0, False)  # the line state last given to the USB host (baud sent, client present)
    touched: bool = False  # the touch was taken (forwarded) and the board has not left yet
    out_at_enum: int = 0  # the device's OUT byte count when its port was made
    written: int = 0  # the device has taken every byte given to the USB host when its OUT count reaches this
    samba: SambaFramer = field(default_factory=lambda: SambaFramer())  # the client's write boundaries (bootloader)
    unplugged: bool = False  # its cable was pulled (--control): never listed again
    deaf: bool = False  # ignores the 1200-baud touch (--control): its bootloader's port never appears

    @property
    def tag(self) -> str:
        """The stable name's tail: mc01 .. mc16, primary."""
        return self.link.rsplit("ttyACM-", 1)[-1]

    def entry(self) -> dict:
        """The board's line of the listing: the fields pyserial's list_ports gives, plus its mode and pty."""
        assert self.port is not None and self.device is not None
        d = self.device
        vid, pid = d.vid, d.pid
        location = f"1-{self.k + 1}:1.0"
        return {
            "device": self.link,
            "vid": vid,
            "pid": pid,
            "serial_number": self.serial,
            "location": location,
            "description": f"{d.product} (emulated {self.name})",
            "manufacturer": d.manufacturer,
            "product": d.product,
            "hwid": f"USB VID:PID={vid:04X}:{pid:04X} SER={self.serial} LOCATION={location}",
            "mode": self.mode,
            "pty": self.port.path,
            "enumeration": self.enumerations,  # 1 at power-up, one more each time it comes back
        }


def serial_number(k: int) -> str:
    """A stand-in serial number for a board's place, until its descriptors say the real one (on a XIAO the chip's
    unique id as 32 hex digits, which the tier makes unique per board)."""
    return f"4D43454D{k + 1:024X}"  # "MCEM" then the place


def write_listing(path: Path, entries: list[dict]) -> None:
    """The listing, atomically (a reader sees the old file or the new one, never a part)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(entries, indent=1) + "\n")
        os.replace(tmp, path)
    finally:
        if tmp.exists():  # interrupted between the two
            tmp.unlink()


class Boards:
    """The world's boards behind their ports: service() after each stretch of world time moves the bytes, follows
    each board's USB state (enumerated or gone) and takes the touches."""

    def __init__(self, world, boards: list[Board], listing: Path, bootloader: str | None) -> None:
        self.world = world
        self.boards = boards
        self.listing = listing
        self.bootloader_problem = bootloader  # None: a touch resets into the bootloader
        # the one switch: the touch reaches the firmware (which erases its first row and resets into the bootloader)
        # as the line coding and DTR a laptop sends, or, while the tier cannot run the bootloader, it is kept from
        # the firmware and the board is reset from outside
        self.forward_touch = bootloader is None
        self.dirty = True
        self.touches = 0
        for b in boards:
            world.usb_attach(b.index, "linux")  # the cables are in from power-up
            b.resets = int(world.info(b.index).resets)

    def up(self) -> int:
        return sum(1 for b in self.boards if b.mode)

    def service(self) -> None:
        w = self.world
        ports = [b.port for b in self.boards if b.port is not None]
        readable = set(select.select(ports, [], [], 0)[0]) if ports else set()
        for b in self.boards:
            usb = w.usb_info(b.index)
            resets = int(w.info(b.index).resets)
            if resets != b.resets:  # it reset (asked or not): the OS saw it leave
                b.resets, b.resetting = resets, False
                self._gone(b)
            if b.mode and (not usb.configured or w.usb_device(b.index).enumerations != b.enumerations_seen):
                self._gone(b)  # it left the bus, or came back between two looks: a new port either way
            if b.unplugged:
                w.usb_read(b.index)  # what it sends goes nowhere
                continue
            if not b.mode and usb.configured and not b.resetting:
                self._enumerated(b)
            out = w.usb_read(b.index)
            if b.port is None or b.port not in ports:  # a port made just now is looked at from the next service on
                continue
            data, present = b.port.poll(b.port in readable)
            if present != b.port.client:
                b.port.client = present
                b.held = bytearray()
                b.samba = SambaFramer()
                b.touched = b.touched and not present
            self._line(b, present, int(usb.control_transfers))
            b.held += data
            # as an OS's open() returns once the device took the line state (its control transfers): the client's
            # first bytes follow them
            taken = int(usb.out_bytes) >= b.written or (b.mode == BOOTLOADER and b.samba.continues())
            if b.held and usb.control_transfers >= b.line_state_at and taken:
                n = b.samba.transfer(b.held) if b.mode == BOOTLOADER else len(b.held)
                sent = w.usb_write(b.index, bytes(b.held[:n])) if n else 0
                if sent < n:
                    say(f"{b.name}: the USB host's buffer is full ({sent} of {n} bytes taken)")
                b.written = max(b.written, int(usb.out_bytes)) + sent
                del b.held[:n]
            b.port.send(out)
            if not present and not b.touched and b.port.touched() and not b.deaf:
                self.on_touch(b)
        if self.dirty:
            write_listing(self.listing, [b.entry() for b in self.boards if b.mode and b.port is not None])
            self.dirty = False

    def _line(self, b: Board, present: bool, transfers: int) -> None:
        """The client's line state to the board as cdc_acm sends it: its open and close as DTR and RTS, its speed as
        the line coding. A touch that is not forwarded keeps 1200 baud from the firmware (its own reset would need
        the bootloader and a flash controller that programs)."""
        assert b.port is not None
        baud = b.port.baud()  # a close keeps the speed the client left
        if baud == TOUCH_BAUD and (not self.forward_touch or b.deaf):
            baud = 0  # the firmware keeps the line coding it has
        sent = baud or b.line[0]
        if (sent, present) == b.line:
            return
        requests = (present != b.line[1]) + (sent != b.line[0])
        b.line = (sent, present)
        b.line_state_at = transfers + requests if present else 0
        self.world.usb_line(b.index, baud, present, present)

    def _gone(self, b: Board) -> None:
        """The board left the bus (a reset): the OS drops its port."""
        if b.port is not None:
            b.port.close()
            b.port = None
        self.dirty = self.dirty or bool(b.mode)
        b.mode = ""

    def _enumerated(self, b: Board) -> None:
        """The board enumerated: a new port behind its stable name, in the mode the last reset chose."""
        b.port = PtyPort(b.link)
        b.enumerations += 1
        b.device = d = self.world.usb_device(b.index)
        b.enumerations_seen = d.enumerations
        b.serial = d.serial or b.serial
        b.line = (9600, False)  # a new tty: cdc_acm's probe set 9600 baud, DTR and RTS low
        b.touched = False
        b.written, b.samba, b.held = 0, SambaFramer(), bytearray()
        b.out_at_enum = int(self.world.usb_info(b.index).out_bytes)
        b.mode = self.mode_of(b)
        self.dirty = True

    def mode_of(self, b: Board) -> str:
        """What the board enumerated as: the idProduct of the device descriptor it sent the tier's USB host (the
        application's or the bootloader's PID), else what its last reset chose (the touch's hook)."""
        pid = getattr(b.device, "pid", None)
        return MODES.get(pid, b.comes_back_as) if pid is not None else b.comes_back_as

    def on_touch(self, b: Board) -> None:
        """The 1200-baud touch: the hook where a reset chooses what runs. With the bootloader, the board would come
        back in it (BOOTLOADER); without, the application restarts directly (one line says so)."""
        self.touches += 1
        if self.forward_touch:
            b.comes_back_as = BOOTLOADER
            b.touched = True  # the line state reached the firmware, which resets by itself (its first row erased)
            return
        b.comes_back_as = APPLICATION
        say(f"{b.name}: 1200-baud touch: {self.bootloader_problem}; the application restarts directly")
        self._gone(b)
        b.resetting = True
        self.world.reset(b.index)

    def read_flash(self, b: Board, start: int = 0, n: int = FLASH_SIZE) -> bytes:
        """The board's flash (what bossac reads back, without the bootloader's help)."""
        return self.world.read_mem(b.index, start, n)

    def unplug(self, b: Board) -> None:
        """Pull the board's cable: its port goes as the OS drops it (a client's next read or write fails) and it is
        not listed again (the board itself is left to run, unseen)."""
        b.unplugged = True
        self._gone(b)

    def control(self, where: Path) -> None:
        """Requests dropped as empty files in the control directory (each removed once done): unplug-TAG pulls a
        board's cable (unplug-TAG-at-N: once its port has taken N bytes from the client, e.g. mid-upload), deaf-TAG
        makes it ignore the 1200-baud touch, dump writes every board's flash to
        flash-TAG.bin (then done-dump); TAG is mc01..mc16 or primary."""
        try:
            names = sorted(p.name for p in where.iterdir())
        except OSError:
            return
        by_tag = {b.tag: b for b in self.boards}
        for name in names:
            what, _, rest = name.partition("-")
            tag, _, at = rest.partition("-at-")
            if what in ("unplug", "deaf") and tag in by_tag:
                b = by_tag[tag]
                if what == "unplug":
                    taken = int(self.world.usb_info(b.index).out_bytes) if b.mode else 0
                    if at.isdigit() and (not b.mode or taken - b.out_at_enum < int(at)):
                        continue  # not yet: its port has not taken that many bytes
                    say(f"{b.name}: unplugged" + (f" after {taken - b.out_at_enum} bytes to its port" if at else ""))
                    self.unplug(b)
                else:
                    say(f"{b.name}: ignores the 1200-baud touch from now on")
                    b.deaf = True
            elif name == "dump":
                for b in self.boards:
                    tmp = where / f".flash-{b.tag}.tmp"
                    tmp.write_bytes(self.read_flash(b))
                    os.replace(tmp, where / f"flash-{b.tag}.bin")
                (where / "done-dump").touch()
            else:
                continue
            (where / name).unlink(missing_ok=True)

    def close(self) -> None:
        for b in self.boards:
            if b.port is not None:
                b.port.close()
                b.port = None
        try:
            self.listing.unlink()
        except FileNotFoundError:
            pass


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator boards",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator boards --ports-json /tmp/rig/ports.json            # 17 boards\n"
        "  python -m metacell_tools.flash identify --ports-json /tmp/rig/ports.json   # in another shell\n"
        "  python -m host_emulator boards --count 3 --ports-json /tmp/rig/ports.json --dev-dir /tmp/rig/dev",
    )
    ap.add_argument("scene", nargs="?", default="default", help="scene whose parameters the boards get (default)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override, as for run")
    ap.add_argument(
        "--count", type=int, default=N_BOARDS, help="boards: the first N of cells 1..16, primary (default 17)"
    )
    ap.add_argument("--blank", action="store_true", help="boards with only the bootloader (needs MC_BOOTLOADER)")
    ap.add_argument("--ports-json", required=True, metavar="PATH", help="where the port listing is written")
    ap.add_argument(
        "--dev-dir",
        default=None,
        metavar="DIR",
        help="directory of the ports' stable names (default: beside PATH, named after it: ports.json -> ports-dev)",
    )
    ap.add_argument(
        "--usb-packet-us",
        type=float,
        default=50.0,
        metavar="US",
        help="the emulated USB host's time to move one packet, in microseconds (default %(default)g)",
    )
    ap.add_argument(
        "--control",
        default=None,
        metavar="DIR",
        help="directory watched for requests (empty files): unplug-TAG[-at-N] (the board ignores the 1200-baud "
        "touch), dump (every board's flash to flash-TAG.bin, then done-dump); TAG is mc01..mc16 or primary",
    )
    ap.add_argument(
        "--plant",
        action="store_true",
        help="start the plant once every board runs its application (default: kept at rest)",
    )
    ap.add_argument("--speed", type=float, default=1.0, help="most simulated seconds per wall second (default 1)")
    ap.add_argument(
        "--exit-with-parent",
        action="store_true",
        help="stop (as on SIGTERM) when the process that started this one is gone: a tool that brings the boards "
        "up for its own run and is killed leaves none behind",
    )
    return ap


def boards_main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if not 1 <= args.count <= N_BOARDS:
        say(f"--count must be 1..{N_BOARDS}, got {args.count}")
        return 2
    if not 1e-3 <= args.speed <= 1e3:
        say(f"--speed must be in 0.001..1000, got {args.speed}")
        return 2
    if args.blank:
        problem = bootloader_problem()
        if problem is not None:
            say(f"--blank needs the XIAO's bootloader in the image tier: {problem}")
            return 2
    listing = Path(args.ports_json)
    dev_dir = Path(args.dev_dir) if args.dev_dir else listing.with_name(f"{listing.stem}-dev")
    try:
        listing.parent.mkdir(parents=True, exist_ok=True)
        made_dir = not dev_dir.exists()
        dev_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        say(f"cannot make {listing.parent} or {dev_dir}: {e.strerror or e}")
        return 2
    try:
        return _run(args, listing, dev_dir)
    finally:
        if made_dir:
            try:
                dev_dir.rmdir()
            except OSError:
                pass


def _world(args):
    """The world of the first --count boards with the scene's parameters (its plant at rest until _run starts it)."""
    from ..models.options import ConfigError
    from ..scene import load_scene
    from . import ImageTierUnavailable
    from .build import build_images
    from .model import WINDOW_S
    from .world import World, WorldConfig, WorldError

    cells = min(args.count, 16)
    try:
        sc = load_scene(args.scene, args.set)
        if sc.cells < cells:
            return None, f"scene {sc.name!r} has {sc.cells} cells, fewer than the {cells} boards asked for"
        p = sc.params  # the first `cells` cells of the scene
        params = dataclasses.replace(p, cells=cells, **{k: getattr(p, k)[:cells] for k in p.per_cell_keys})
        io = sc.options.image
        boot = "bootloader" if bootloader_problem() is None else io.boot
        cfg = WorldConfig(
            window_s=WINDOW_S,
            threads=io.threads,
            cycle_model=io.cycle_model,
            ff=io.fast_forward,
            ff_timed=io.fast_forward_timed,
            round_s=io.round_s,
            boot=boot,
            blank=args.blank,
            usb_packet_us=args.usb_packet_us,
        )
        primary = args.count > 16
        images = None if args.blank else build_images(cells, primary=primary)
        return World(params, images, options=sc.options, config=cfg, primary=primary), None
    except (ConfigError, ValueError, KeyError, OSError) as e:
        return None, str(e)
    except (ImageTierUnavailable, WorldError) as e:
        return None, f"the image tier cannot run: {e}"


def _run(args, listing: Path, dev_dir: Path) -> int:
    from .world import WorldError

    t_start = time.monotonic()
    world, problem = _world(args)
    if world is None:
        say(str(problem).splitlines()[0] if problem else "cannot start")
        return 2
    names = [(b.index, b.name, "primary" if b.role == "primary" else f"mc{b.cell:02d}") for b in world.boards]
    boards = [Board(k, i, n, str(dev_dir / f"ttyACM-{tag}"), serial_number(k)) for k, (i, n, tag) in enumerate(names)]
    rig = Boards(world, boards, listing, bootloader_problem(world.lib))
    stop: list[int] = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    signal.signal(signal.SIGHUP, lambda *a: stop.append(1))
    status = 0
    announced = False
    planted = not args.plant  # the plant runs (or is to stay at rest)
    t_wall0, t_world0 = time.monotonic(), world.t
    control = Path(args.control) if args.control else None
    looked = 0.0
    parent = os.getppid()
    try:
        while not stop:
            if args.exit_with_parent and os.getppid() != parent:
                say("the process that started the boards is gone: stopping")
                break
            rig.service()
            if control is not None and time.monotonic() - looked > CONTROL_EVERY_S:
                looked = time.monotonic()
                rig.control(control)
            if not announced and rig.up() == len(boards):
                announced = True
                print(
                    f"{len(boards)} boards up at t = {world.t:.3f} s ({time.monotonic() - t_start:.1f} s after start): "
                    f"ports in {dev_dir}, listing {listing}",
                    flush=True,
                )
            if not planted and all(b.mode == APPLICATION for b in boards):
                planted = True
                print(f"plant started at t = {world.start_plant():.3f} s", flush=True)
            lead = (world.t - t_world0) / args.speed - (time.monotonic() - t_wall0)
            if lead > 0:  # ahead of real time: wait for the clients (or for real time to catch up)
                held = [b.port for b in boards if b.port is not None and b.port.client]
                select.select(held, [], [], min(lead, WAIT_MAX_S))
                continue
            if lead < -LAG_MAX_S:  # behind: no sprint later
                t_wall0 = time.monotonic() - (world.t - t_world0) / args.speed - LAG_MAX_S
            busy = any(b.mode == BOOTLOADER and b.port is not None and b.port.client for b in boards)
            world.run_to(world.t + (CHUNK_BUSY_S if busy else CHUNK_S))
    except KeyboardInterrupt:
        pass
    except WorldError as e:
        say(f"stopped at t = {world.t:.3f} s: {e}")
        status = 3
    finally:
        rig.close()
    print(f"boards: {len(boards)} boards ran {world.t:.1f} s, {rig.touches} touches; ports and listing removed")
    return status


if __name__ == "__main__":
    raise SystemExit(boards_main())
