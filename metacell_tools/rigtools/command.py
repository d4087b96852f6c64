"""Command tool: set parameters, enable drives, perturb cells, zero encoders through the primary (python-can, any bus).

    python -m metacell_tools.rigtools.command -c /dev/ttyACM0@115200 set 8 sigma 0.072
    python -m metacell_tools.rigtools.command -c /dev/pts/3@115200 perturb 8 --torque 0.02 --duration 0.1
    python -m metacell_tools.rigtools.command -c ... enable all on | zero all | bemf 3 off | pwm-limit 5 1200
    python -m metacell_tools.rigtools.command -c ... clear-faults all
    python -m metacell_tools.rigtools.command -c ... info all      # identity, protocol map id and parameters in force
    python -m metacell_tools.rigtools.command -c ... apply out/design/design.json   # every cell's own parameters

A serial port has one reader: while the logger runs, schedule commands with its --do option.
Every command waits for the primary's CMD_RESULT (the cell's verdict, or NACK/TIMEOUT/
BUSY/NO_ROOM/...). Exit codes: 0 every addressed cell answered OK, 1 some cell answered
otherwise (or not at all), 2 bad input, 3 the port could not be opened.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import tomllib
from collections.abc import Callable, Iterable, Sequence
from fractions import Fraction
from pathlib import Path

import can

from metacell_common.cli import unexpected
from metacell_common.reaction import REACTION_DEFAULTS, REACTION_REGISTERS
from protocol import codec

from . import proto, rigconfig
from .slcanbus import open_bus

PARAM_REGS = {"k_ab": "K_AB", "sigma": "SIGMA", "k1": "K1", "k2": "K2", "alpha_star": "ASTAR", "astar": "ASTAR"}
CTRL_RATE_HZ = 2000  # cell control tick (platformio.ini MC_CTRL_RATE_HZ)
PWM_TOP = 2400  # the PWM period in timer ticks (platformio.ini MC_PWM_TOP)
SUPPLY_V, VMAX_V = 9.0, 5.86  # the scenes' defaults (host_emulator.params): supply and the drivers' cap


def number(text: str) -> float:
    """A number, or a fraction such as 9/125: the syntax of the emulator's --set and scene overrides (ranges, and
    inf / nan, are refused by `build` with a one-line error)."""
    try:
        return float(Fraction(text.strip())) if "/" in text else float(text)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"expected a number or a fraction such as 9/125, got {text!r}") from None


def physical_to_wire(name: str, value: float) -> int:
    """SI value (N*m/rad, rad for alpha_star) -> integer register value (protocol.codec: uN*m/rad, urad),
    ValueError if the register cannot carry it (the cell answers RANGE for what it does not accept)."""
    try:
        return codec.to_register(PARAM_REGS[name], "value", value, firmware=False)
    except codec.RangeError as e:
        raise ValueError(f"{name}: {e}") from None


class RigClient:
    """Send CMD frames and wait for the matching CMD_RESULT on an open python-can bus."""

    def __init__(
        self, bus: can.BusABC, timeout: float = 1.0, on_message: Callable[[can.Message], None] | None = None
    ) -> None:
        self.bus = bus
        self.timeout = timeout
        self.on_message = on_message  # gets every frame received while waiting
        self.chunks: dict[int, list[bytes]] = {}  # cell -> BLOCK_DATA payloads received
        self.seq = int(time.time()) & 0xFF

    def command(self, cells: Iterable[int], reg: str, **values: int) -> dict:
        """Send reg to every cell in `cells`; returns {cell: result name}."""
        pending = {}
        for j in cells:
            self.seq = (self.seq + 1) & 0xFF
            data = proto.cmd_data(reg, self.seq, **values)
            self.bus.send(can.Message(arbitration_id=proto.cmd_frame_id(j), data=data, is_extended_id=False))
            pending[(j, self.seq)] = reg
        out = {}
        deadline = time.monotonic() + self.timeout + 0.1 * len(pending)
        rid = proto.REGISTERS[reg]["id"]
        while pending and time.monotonic() < deadline:
            msg = self.bus.recv(timeout=0.05)
            if msg is None:
                continue
            if self.on_message:
                self.on_message(msg)
            kind, cell = proto.frame_kind(msg.arbitration_id, proto.MAX_CELLS)  # answers of any cell it asked
            if kind == "BLOCK_DATA" and cell is not None:  # a per-cell frame
                self.chunks.setdefault(cell, []).append(bytes(msg.data))
            elif (
                kind == "CMD_RESULT"
                and cell is not None
                and len(msg.data) >= 3
                and msg.data[0] == rid
                and (cell, msg.data[1]) in pending
            ):
                del pending[(cell, msg.data[1])]
                out[cell] = proto.RESULT_NAMES.get(msg.data[2], f"0x{msg.data[2]:02X}")
            elif kind == "PRIMARY_REJECT":
                print(
                    f"primary rejected a frame: {proto.database().decode_message(msg.arbitration_id, msg.data)}",
                    file=sys.stderr,
                )
        for j, _ in pending:
            out[j] = "NO_ANSWER"
        return out

    def info(self, cells: Sequence[int], blocks: Iterable[str] = ("IDENT", "PARAMS")) -> dict:
        """{cell: {"IDENT": {...}, "PARAMS": {...}, "results": [...]}} read back through the primary (POINTER
        commands), one entry per block in `blocks` that arrived whole (CRC checked)."""
        self.chunks = {}
        res: dict[int, list[str]] = {}
        for name in blocks:
            for j, r in self.command(cells, "POINTER", block=proto.D.BLOCKS[name]["id"]).items():
                res.setdefault(j, []).append(r)
        out = {}
        for j in cells:
            out[j] = proto.reassemble_blocks(self.chunks.get(j, []))
            out[j]["results"] = res.get(j, [])
        return out


# ---- apply: every cell's own reaction parameters from a design ------------------------------------------------
APPLY_ORDER = ("K_AB", "SIGMA", "ASTAR")  # then K1 and K2 in the order that keeps k1 > k2 after each write
PARAM_FIELDS = {"K_AB": "k_ab", "SIGMA": "sigma", "K1": "k1", "K2": "k2", "ASTAR": "astar"}  # PARAMS block fields


class ApplyError(ValueError):
    """A design the cells would refuse (checked before anything is sent); the message names the key and cell."""


def design_registers(path: str) -> dict[int, dict[str, int]]:
    """{cell: {register: raw value}} of a design.json (`python -m host_emulator design`) or a scene .toml: each
    reaction parameter one value or one per cell, converted as the registers carry them and checked against the
    firmware's acceptance (range, k1 > max(k2, 0)); ApplyError naming the key and the cell otherwise."""
    f = Path(path)
    if f.is_dir():
        f = f / "design.json"
    try:
        if f.suffix == ".toml":
            doc = tomllib.loads(f.read_text())
            params, cells = doc.get("params", {}), doc.get("cells", proto.N_CELLS)
        else:
            doc = json.loads(f.read_text())
            params, cells = doc["params"], doc.get("cells", proto.N_CELLS)
        rig_n = rig_cells()
    except (OSError, ValueError, KeyError) as e:
        raise ApplyError(f"{path}: not a readable design.json or scene .toml ({type(e).__name__}: {e})") from None
    if isinstance(cells, list) and len(cells) == 2 and all(isinstance(d, int) and d >= 1 for d in cells):
        cells = cells[0] * cells[1]  # a sheet [rows, cols]: its cells row by row
    if not isinstance(cells, int) or not 1 <= cells <= rig_n:
        raise ApplyError(f"{path}: cells = {cells!r}; the rig has {rig_n}")
    out: dict[int, dict[str, int]] = {j: {} for j in range(1, cells + 1)}
    for name, reg in REACTION_REGISTERS.items():
        v = params.get(name, REACTION_DEFAULTS[name])
        vals = v if isinstance(v, list) else [v] * cells
        if len(vals) != cells:
            raise ApplyError(f"params.{name}: {len(vals)} values for {cells} cells")
        for j, x in enumerate(vals, start=1):
            where = f"params.{name}[{j}] (cell {j})" if isinstance(v, list) else f"params.{name}"
            try:
                out[j][reg] = codec.to_register(reg, "value", float(x), firmware=True)
            except (TypeError, ValueError) as e:
                raise ApplyError(f"{where} = {x!r}: {e}") from None
    for j, r in out.items():
        if not (r["K1"] > 0 and r["K1"] > r["K2"]):
            raise ApplyError(
                f"params.k1 = {r['K1'] * 1e-6:g}, params.k2 = {r['K2'] * 1e-6:g} at cell {j}: the firmware needs "
                "k1 > max(k2, 0)"
            )
    return out


def design_config(path: str) -> dict[str, int] | None:
    """The cells' configuration a design assumes: {"bemf": 0/1, "pwm_limit": timer ticks in force} from design.json's
    `assumes.firmware` (or a scene .toml's params: bemf_comp, and the PWM limit the experiment runner's setup leaves
    in force for vmax_v, supply_v, pwm_top); None for a design.json written before designs recorded it. ApplyError
    if unreadable."""
    f = Path(path)
    if f.is_dir():
        f = f / "design.json"
    try:
        if f.suffix == ".toml":
            p = tomllib.loads(f.read_text()).get("params", {})
            supply, vmax = float(p.get("supply_v", SUPPLY_V)), float(p.get("vmax_v", VMAX_V))
            top = int(p.get("pwm_top", PWM_TOP))
            fw = {
                "bemf_comp": bool(p.get("bemf_comp", False)),
                "pwm_limit_ticks": min(  # the runner's PWM_LIMIT, clamped by the firmware to its duty_max
                    round(min(vmax, supply) / supply * top), round(vmax * 1000) * top // round(supply * 1000)
                ),
            }
        else:
            fw = json.loads(f.read_text()).get("assumes", {}).get("firmware")
            if fw is None:
                return None
        return {"bemf": int(bool(fw["bemf_comp"])), "pwm_limit": int(fw["pwm_limit_ticks"])}
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ApplyError(f"{path}: its firmware configuration is unreadable ({type(e).__name__}: {e})") from None


def read_config(client: RigClient, cells: Sequence[int]) -> dict[int, dict[str, int] | None]:
    """{cell: {"bemf": back-EMF compensation on (SNAPSHOT flags), "pwm_limit": PWM limit in force (PARAMS)}}, None
    for a cell whose blocks did not come back."""
    info = client.info(cells, blocks=("SNAPSHOT", "PARAMS"))
    out: dict[int, dict[str, int] | None] = {}
    for j in cells:
        d = info.get(j, {})
        if "SNAPSHOT" not in d or "PARAMS" not in d:
            out[j] = None
            continue
        out[j] = {
            "bemf": (int(d["SNAPSHOT"]["flags"]) >> proto.D.CELL_FLAGS["BEMF"]) & 1,
            "pwm_limit": int(d["PARAMS"]["pwm_limit"]),
        }
    return out


def _config_text(c: dict[str, int] | None) -> str:
    if c is None:
        return "no answer"
    return f"back-EMF compensation {'on' if c['bemf'] else 'off'}, PWM limit {c['pwm_limit']}"


def check_config(client: RigClient, cells: Sequence[int], config: dict[str, int], configure: bool, report) -> bool:
    """The cells' configuration against the design's: True when every cell has it (configure: after setting it on
    those that differ, and reading it back). Without configure a difference is refused, nothing sent."""
    have = read_config(client, cells)
    differ = [j for j in cells if have[j] != config]
    if not differ:
        return True
    silent = [j for j in differ if have[j] is None]
    if silent:
        report(f"refused: cell(s) {','.join(map(str, silent))} did not report their configuration; nothing written")
        return False
    if not configure:
        for j in differ:
            report(f"cell {j:2d}: {_config_text(have[j])}; the design assumes {_config_text(config)}")
        report(
            f"refused: {len(differ)} cell(s) run another configuration than the design assumes; nothing written "
            "(--configure sets it)"
        )
        return False
    for reg, values in (("PWM_LIMIT", {"ticks": config["pwm_limit"]}), ("BEMF", {"on": config["bemf"]})):
        res = client.command(differ, reg, **values)
        bad = {j: r for j, r in res.items() if r != "OK"}
        if bad:
            report(f"refused: {reg} answered " + ", ".join(f"cell {j}: {r}" for j, r in sorted(bad.items())))
            return False
    after = read_config(client, differ)
    wrong = [j for j in differ if after[j] != config]
    for j in wrong:
        report(f"cell {j:2d}: configured, but reads back {_config_text(after[j])}")
    if not wrong:
        report(f"configured {len(differ)} cell(s): {_config_text(config)}")
    return not wrong


def _writes(old: dict[str, int], new: dict[str, int]) -> list[tuple[str, int]]:
    """The register writes taking one cell from `old` to `new` (raw values), K1/K2 in an order that keeps
    k1 > k2 after each: K1 first when the new k1 exceeds the old k2, else K2 first."""
    w = [(reg, new[reg]) for reg in APPLY_ORDER]
    pair = [("K1", new["K1"]), ("K2", new["K2"])]
    return w + (pair if new["K1"] > old["K2"] else pair[::-1])


def read_params(client: RigClient, cells: Sequence[int]) -> dict[int, dict[str, int] | None]:
    """{cell: {register: raw value in force}} read back through the primary (None: no PARAMS block came back)."""
    info = client.info(cells, blocks=("PARAMS",))
    out: dict[int, dict[str, int] | None] = {}
    for j in cells:
        p = info.get(j, {}).get("PARAMS")
        out[j] = None if p is None else {reg: int(p[f]) for reg, f in PARAM_FIELDS.items()}
    return out


def apply_design(
    client: RigClient,
    want: dict[int, dict[str, int]],
    report=print,
    config: dict[str, int] | None = None,
    configure: bool = False,
) -> bool:
    """Write every cell's parameters, read them back; all or nothing: when some cell does not answer before, or
    rejects a write, every cell already written gets its old values back (and nothing else is sent). True when
    every cell holds the design's values afterwards. config (design_config): first the cells' back-EMF
    compensation and PWM limit must be the design's, else nothing is written (configure: set them first)."""
    cells = sorted(want)
    if config is not None and not check_config(client, cells, config, configure, report):
        return False
    before = read_params(client, cells)
    missing = [j for j in cells if before[j] is None]
    if missing:
        report(f"refused: cell(s) {','.join(map(str, missing))} did not report their parameters; nothing written")
        return False
    done: list[int] = []
    failed = None
    for j in cells:
        old = before[j]
        assert old is not None
        for reg, raw in _writes(old, want[j]):
            r = client.command([j], reg, value=raw).get(j, "NO_ANSWER")
            if r != "OK":
                failed = (j, reg, raw, r)
                break
        done.append(j)
        if failed:
            break
    if failed:
        j, reg, raw, r = failed
        report(
            f"refused: cell {j} answered {r} to {reg} = {codec.from_register(reg, 'value', raw):g}; "
            f"restoring the {len(done)} cell(s) written"
        )
        for k in done:
            old = before[k]
            assert old is not None
            for reg2, raw2 in _writes(want[k], old):
                client.command([k], reg2, value=raw2)
        back = read_params(client, done)
        bad = [k for k in done if back[k] != before[k]]
        if bad:
            report(f"WARNING: cell(s) {','.join(map(str, bad))} could not be restored; check with `info`")
        return False
    after = read_params(client, cells)
    wrong = [j for j in cells if after[j] != want[j]]
    for j in wrong:
        report(f"cell {j:2d}: read back {after[j]}, expected {want[j]}")
    for j in cells:
        if j not in wrong:
            v = want[j]
            report(
                f"cell {j:2d}: k_ab {v['K_AB'] * 1e-6:g} sigma {v['SIGMA'] * 1e-6:g} k1 {v['K1'] * 1e-6:g} "
                f"k2 {v['K2'] * 1e-6:g} N*m/rad, alpha* {v['ASTAR'] * 1e-6:g} rad: written and read back"
            )
    return not wrong


def rig_cells() -> int:
    """The rig's cell count: its config's (rig/rig.toml, rigconfig), else the rig as built's 16."""
    return rigconfig.n_cells(rigconfig.read())


def _cells(text: str) -> list[int]:
    try:
        n = rig_cells()
    except rigconfig.RigConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    if text == "all":
        return list(range(1, n + 1))
    try:
        cells = []
        for part in (p.strip() for p in text.split(",")):
            lo, sep, hi = part.partition("-")  # "1-16" is cells 1..16
            a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
            if a > b:
                raise ValueError(f"range {part!r} runs backwards")
            cells += [j for j in range(a, b + 1) if j not in cells]
        for j in cells:
            proto.cell_address(j)
            if j > n:
                raise ValueError(f"cell {j}: the rig has {n} cells (its config: {rigconfig.DEFAULT_PATH})")
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"cells: {e}") from None
    return cells


def _onoff(text: str) -> int:
    t = text.lower()
    if t in ("on", "1", "true"):
        return 1
    if t in ("off", "0", "false"):
        return 0
    raise argparse.ArgumentTypeError(f"expected on/off, got {text!r}")


def parser():
    pre = "python -m metacell_tools.rigtools.command -c /dev/ttyACM0@115200"
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.rigtools.command",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        f"  {pre} set 8 sigma 0.072\n"
        f"  {pre} perturb 8 --torque 0.02 --duration 0.1\n"
        f"  {pre} enable 1-16 on\n"
        f"  {pre} info all\n"
        "  python -m metacell_tools.rigtools.command SUBCOMMAND --help     # one command's arguments\n"
        "exit codes: 0 every addressed cell answered OK, 1 some cell did not, 2 bad input, 3 port not opened.",
    )
    ap.add_argument("-i", "--interface", default="slcan", help="python-can interface (default slcan)")
    ap.add_argument("-c", "--channel", required=True, help="e.g. /dev/ttyACM0@115200 or the emulator's pty@115200")
    ap.add_argument("--timeout", type=float, default=1.0, help="seconds to wait for each result")
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="COMMAND", help="what to send")
    cells_help = "cells: 'all', a number 1-16, a range or a list (e.g. 8, 1-16, 1-4,7)"

    def add(name, help, example):
        return sub.add_parser(
            name,
            help=help,
            description=help[0].upper() + help[1:] + ".",
            formatter_class=argparse.RawDescriptionHelpFormatter,
            epilog=f"example:\n  {pre} {example}",
        )

    s = add("set", "set a reaction parameter (SI units: N*m/rad; alpha_star in rad)", "set 1-16 sigma 9/125")
    s.add_argument("cells", type=_cells, help=cells_help)
    s.add_argument(
        "name", choices=sorted(PARAM_REGS), metavar="NAME", help="parameter: " + ", ".join(sorted(PARAM_REGS))
    )
    s.add_argument(
        "value",
        type=number,
        help="value in SI units (N*m/rad; alpha_star and astar in rad): a number or a fraction such as 9/125",
    )
    p = add("perturb", "perturbing torque on one chain for a while", "perturb 8 --torque 0.02 --duration 0.1")
    p.add_argument("cells", type=_cells, help=cells_help)
    p.add_argument("--chain", choices=("alpha", "beta"), default="alpha", help="chain pushed (default alpha)")
    p.add_argument(
        "--torque", type=number, required=True, help=f"N*m (a fraction allowed), |torque| <= {codec.PERTURB_MAX_NM:g}"
    )
    p.add_argument("--duration", type=float, required=True, help="seconds (at the 2 kHz control tick)")
    for name in ("enable", "bemf"):
        what = "drive enable" if name == "enable" else "back-EMF compensation"
        e = add(name, f"{what} on/off", f"{name} all {'off' if name == 'enable' else 'on'}")
        e.add_argument("cells", type=_cells, help=cells_help)
        e.add_argument("state", type=_onoff, help="on or off (also 1/0, true/false)")
    z = add("zero", "make the current positions the encoders' zero", "zero all")
    z.add_argument("cells", type=_cells, help=cells_help)
    i = add("info", "read identity and parameters in force back from the cells", "info all")
    i.add_argument("cells", type=_cells, help=cells_help)
    c = add("clear-faults", "clear latched faults", "clear-faults 3,7")
    c.add_argument("cells", type=_cells, help=cells_help)
    a = add(
        "apply",
        "write every cell's reaction parameters from a design (design.json, its directory, or a scene .toml), read "
        "them back; all or nothing",
        "apply out/design_l10/design.json",
    )
    a.add_argument("design", help="design.json of `python -m host_emulator design` (or its directory, or a .toml)")
    a.add_argument(
        "--configure",
        action="store_true",
        help="set the back-EMF compensation and PWM limit the design assumes where a cell differs (default: refuse, "
        "nothing written)",
    )
    w = add("pwm-limit", "PWM duty limit in timer ticks (<= 2400; capped at 5.86 V)", "pwm-limit all 1200")
    w.add_argument("cells", type=_cells, help=cells_help)
    w.add_argument("ticks", type=int, help="timer ticks of the 2400-tick PWM period (0..65535; the cell caps it)")
    return ap


def build(args: argparse.Namespace) -> tuple[str, dict]:
    """(register, payload values) for parsed arguments; ValueError on out-of-range input."""
    if args.cmd == "set":
        return PARAM_REGS[args.name], {"value": physical_to_wire(args.name, args.value)}
    if args.cmd == "perturb":
        if not (math.isfinite(args.torque) and math.isfinite(args.duration)):
            raise ValueError(f"perturb: torque {args.torque} N*m and duration {args.duration} s must be finite")
        try:
            torque = codec.to_register("PERTURB", "torque", args.torque)
        except codec.RangeError as e:
            raise ValueError(f"perturb: {e}") from None
        ticks = round(args.duration * CTRL_RATE_HZ)
        if not 0 < ticks <= codec.raw_range("PERTURB", "ticks")[1]:
            raise ValueError(f"perturb: duration {args.duration} s out of range")
        return "PERTURB", {"chain": 0 if args.chain == "alpha" else 1, "torque": torque, "ticks": ticks}
    if args.cmd in ("enable", "bemf"):
        return args.cmd.upper(), {"on": args.state}
    if args.cmd == "zero":
        return "ZERO", {}
    if args.cmd == "clear-faults":
        return "CLEAR_FAULTS", {}
    if args.cmd == "info":
        return "POINTER", {"block": proto.D.BLOCKS["IDENT"]["id"]}
    if args.cmd == "apply":
        return "APPLY", {}
    if not 0 <= args.ticks <= 65535:
        raise ValueError(f"pwm-limit: {args.ticks} ticks out of range")
    return "PWM_LIMIT", {"ticks": args.ticks}


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except Exception as e:  # noqa: BLE001 - the last guard: one line, never a traceback (MC_DEBUG=1 shows it)
        return unexpected(e, "command")


def _main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        reg, values = build(args)
        want = design_registers(args.design) if args.cmd == "apply" else None
        config = design_config(args.design) if args.cmd == "apply" else None
        if reg != "APPLY":
            proto.pack_payload(reg, **values)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not (math.isfinite(args.timeout) and 0 < args.timeout <= 3600):
        print(f"error: --timeout must be in (0, 3600] s, got {args.timeout}", file=sys.stderr)
        return 2
    try:
        bus = open_bus(args.interface, args.channel)
    except Exception as e:  # python-can and pyserial raise several types
        text = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"error: cannot open {args.channel}: {text}", file=sys.stderr)
        return 3
    if want is not None:
        with bus:
            ok = apply_design(RigClient(bus, args.timeout), want, config=config, configure=args.configure)
        print(f"apply {args.design}: {'every cell holds its parameters' if ok else 'NOT applied'}")
        return 0 if ok else 1
    if args.cmd == "info":

        def si(reg: str, raw: int) -> float:
            return codec.from_register(reg, "value", raw)

        with bus:
            info = RigClient(bus, args.timeout).info(args.cells)
        ok = True
        for j in sorted(info):
            d = info[j]
            if "IDENT" not in d or "PARAMS" not in d:
                print(f"cell {j:2d}: no answer ({', '.join(d['results'])})")
                ok = False
                continue
            i, p = d["IDENT"], d["PARAMS"]
            print(
                f"cell {j:2d}: addr 0x{i['addr']:02X} fw {i['fw_version'] >> 8}.{i['fw_version'] & 255} "
                f"build 0x{i['build']:08X} map 0x{i['map_id']:04X}"
                f"{'' if i['map_id'] == proto.map_id() else ' (MISMATCH)'}"
                f" | k_ab {si('K_AB', p['k_ab']):g} sigma {si('SIGMA', p['sigma']):g} k1 {si('K1', p['k1']):g} "
                f"k2 {si('K2', p['k2']):g} N*m/rad, alpha* {si('ASTAR', p['astar']):g} rad, "
                f"pwm limit {p['pwm_limit']}"
            )
            ok = ok and i["map_id"] == proto.map_id()
        return 0 if ok else 1
    with bus:
        res = RigClient(bus, args.timeout).command(args.cells, reg, **values)
    for j in sorted(res):
        print(f"cell {j:2d}: {reg} -> {res[j]}")
    return 0 if all(r == "OK" for r in res.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
