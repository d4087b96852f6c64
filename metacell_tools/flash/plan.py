"""Turn the inventory and the connected ports into an explicit list of steps: PlatformIO's build, then its upload or
bossac's (toolchain.Toolchain says which)."""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field, replace
from pathlib import Path

from metacell_common.target.build import board_build_env  # the one definition of a board's build

from .addresses import CELL_COUNT
from .boards import Port, xiao_ports
from .bossac import BossacUpload
from .inventory import Board
from .toolchain import Toolchain

ROOT = Path(__file__).resolve().parents[2]


class PlanError(ValueError):
    """The plan cannot be made (missing boards, duplicate serials, bad selection)."""


@dataclass(frozen=True)
class Step:
    board: Board
    port: Port
    env_name: str  # PlatformIO environment: "cell" or "primary"
    env_vars: tuple[tuple[str, str], ...]  # set for this pio run (override the caller's)
    argv: tuple[str, ...]  # PlatformIO: builds, and uploads too unless `upload` is set
    upload: BossacUpload | None = None  # after the build: 1200-baud touch, bootloader port, bossac

    def shell(self) -> str:
        """The exact command, copy-pasteable into a POSIX shell."""
        assigns = " ".join(f"{k}={shlex.quote(v)}" for k, v in self.env_vars)
        return f"{assigns} {shlex.join(self.argv)}" if assigns else shlex.join(self.argv)


@dataclass
class Plan:
    steps: list[Step]
    missing: list[Board] = field(default_factory=list)  # skipped: not connected
    unselected: list[Board] = field(default_factory=list)  # skipped: not in --only
    unknown: list[Port] = field(default_factory=list)  # XIAO boards not in the inventory
    cells: int = CELL_COUNT  # the rig's cells (the inventory's; 16 as built, a sheet up to 64)


def parse_only(text: str | None, cells: int = CELL_COUNT) -> set | None:
    """'1-4,7,primary' -> {1, 2, 3, 4, 7, 'primary'} of a rig of `cells` cells; None means every board."""
    if text is None:
        return None
    sel: set = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if part == "primary":
            sel.add("primary")
            continue
        lo, sep, hi = part.partition("-")
        try:
            a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
        except ValueError:
            raise PlanError(f"--only: {part!r} is not a cell number, range or 'primary'") from None
        if not (1 <= a <= b <= cells):
            raise PlanError(f"--only: {part!r} is outside cells 1..{cells}")
        sel.update(range(a, b + 1))
    if not sel:
        raise PlanError("--only selects nothing")
    return sel


def upload_step(
    board: Board,
    port: Port,
    pio: str = "pio",
    project: Path = ROOT,
    tools: Toolchain | None = None,
    cells: int = CELL_COUNT,
) -> Step:
    """One build+upload of the board's image (board_build_env, for a rig of `cells` cells): with PlatformIO's
    uploader (tools None: `pio` as given) or, when tools.uploader is "bossac", a build followed by bossac's upload
    of its firmware.bin."""
    project = Path(project)
    env_name, env_vars = board_build_env(board.role, board.cell, project, cells=cells)
    if tools is None:
        run: tuple[str, ...] = (pio, "run", "-d", str(project))
    else:
        env_vars += tools.build_env
        run = (*tools.build_prefix, "run") if tools.through_tree else (*tools.build_prefix, "run", "-d", str(project))
    if tools is None or tools.uploader == "pio":
        return Step(
            board, port, env_name, env_vars, (*run, "-e", env_name, "-t", "upload", "--upload-port", port.device)
        )
    assert tools.bossac is not None
    firmware = Path(dict(env_vars)["PLATFORMIO_BUILD_DIR"]) / env_name / "firmware.bin"
    return Step(
        board, port, env_name, env_vars, (*run, "-e", env_name), BossacUpload(tools.bossac, firmware, tools.offset)
    )


def with_toolchain(plan: Plan, tools: Toolchain, project: Path = ROOT) -> Plan:
    """The same boards, each step built and uploaded as tools says."""
    return replace(
        plan, steps=[upload_step(s.board, s.port, project=project, tools=tools, cells=plan.cells) for s in plan.steps]
    )


def with_prebuilt(plan: Plan, tools: Toolchain, images: Path) -> Plan:
    """The same boards, nothing built: bossac uploads images/cellNN/firmware.bin (or primary/), made from the
    firmware.elf beside it when missing. Those are the rig as built's images: a rig of other than 16 cells needs its
    primary built for its cells, so it is refused (PlanError)."""
    if plan.cells != CELL_COUNT:
        raise PlanError(
            f"--prebuilt: the images are the {CELL_COUNT}-cell rig's; this rig has {plan.cells} cells (its primary "
            "must be built for them: flash without --prebuilt)"
        )
    assert tools.bossac is not None
    steps = []
    for s in plan.steps:
        name = "primary" if s.board.role == "primary" else f"cell{s.board.cell:02d}"
        upload = BossacUpload(tools.bossac, Path(images) / name / "firmware.bin", tools.offset)
        steps.append(Step(s.board, s.port, s.env_name, (), (), upload))
    return replace(plan, steps=steps)


def make_plan(
    boards: list[Board],
    ports: list[Port],
    pio: str = "pio",
    project: Path = ROOT,
    only: set | None = None,
    skip_missing: bool = False,
    cells: int = CELL_COUNT,
) -> Plan:
    """The steps of flashing the inventory's boards (a rig of `cells` cells + primary) on the connected ports."""
    xiao = xiao_ports(ports)
    by_serial: dict[str, Port] = {}
    clash = []
    for p in xiao:
        if p.serial_number:
            if p.serial_number in by_serial:
                clash.append(f"serial {p.serial_number} on both {by_serial[p.serial_number].device} and {p.device}")
            by_serial[p.serial_number] = p
    if clash:
        raise PlanError("; ".join(clash))
    known = {b.serial for b in boards}
    plan = Plan(steps=[], unknown=[p for p in xiao if p.serial_number not in known], cells=cells)
    for b in boards:
        key = "primary" if b.role == "primary" else b.cell
        if only is not None and key not in only:
            plan.unselected.append(b)
            continue
        port = by_serial.get(b.serial)
        if port is None:
            plan.missing.append(b)
            continue
        plan.steps.append(upload_step(b, port, pio, project, cells=cells))
    if only is not None:
        listed = {"primary" if b.role == "primary" else b.cell for b in boards}
        absent = sorted(only - listed, key=str)
        if absent:
            raise PlanError("--only names boards the inventory does not have: " + ", ".join(map(str, absent)))
    if plan.missing and not skip_missing:
        raise PlanError(
            "missing board(s): "
            + "; ".join(f"{b.name} serial {b.serial} is not connected" for b in plan.missing)
            + " (connect them, or pass --skip-missing / --only)"
        )
    if not plan.steps:
        raise PlanError("nothing to flash")
    return plan


def describe(plan: Plan) -> str:
    """Human-readable plan: one line per board, then the exact commands."""
    rig = "" if plan.cells == CELL_COUNT else f" (a rig of {plan.cells} cells + primary)"
    lines = [f"{len(plan.steps)} board(s) to flash{rig}:"]
    for s in plan.steps:
        mode = " [bootloader]" if s.port.in_bootloader else ""
        addr = f"addr 0x{s.board.addr:02x}" if s.board.addr is not None else "no bus address"
        label = "primary" if s.board.role == "primary" else f"cell {s.board.cell:2d}"
        lines.append(f"  {label:8s} {addr:15s} serial {s.board.serial} on {s.port.device}{mode}")
    for b in plan.missing:
        lines.append(f"  SKIPPED (not connected): {b.name} serial {b.serial}")
    for b in plan.unselected:
        lines.append(f"  not selected: {b.name} serial {b.serial}")
    for p in plan.unknown:
        lines.append(f"  left alone (not in inventory): {p.device} serial {p.serial_number}")
    lines.append("commands:")
    for s in plan.steps:
        lines.append(f"  {s.shell() or '(prebuilt: ' + str(s.upload.firmware if s.upload else '') + ')'}")
        if s.upload is not None:
            touch = "" if s.port.in_bootloader else f"1200-baud touch of {s.port.device}, then "
            lines.append(f"    {touch}{s.upload.shell()}   (PORT: serial {s.board.serial}'s bootloader port)")
    return "\n".join(lines)
