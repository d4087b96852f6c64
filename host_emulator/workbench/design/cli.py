"""`python -m host_emulator design`: the command line of design(...)."""

from __future__ import annotations

import argparse
import sys

from .constants import REQUIRE
from .driver import design
from .target import DesignError


def design_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator design",
        description="Find reaction-law parameters (global or per cell) that make the pushed chain land on a target "
        "pattern, verified with the firmware in the loop (docs/design.md).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator design --target lambda=10 --push 8 --out out/design_l10\n"
        "  python -m host_emulator design --target walls=5.5,10.5 --push 8 --out out/design_w\n"
        "  python -m host_emulator design --target lambda=7.5 --scene exp1_ccw_ccw --out out/design_l75\n"
        "  python -m host_emulator design --target walls=2.5,5.5 --rest 9-16 --push 4 --out out/half\n"
        "  python -m host_emulator design --sheet 16x16 --target pattern --rest cols=9-16 --push 8x4 --out out/sheet\n"
        "then: python -m host_emulator run out/design_l10/scene.toml\n"
        "      python -m metacell_tools.rigtools.command -c PORT@115200 apply out/design_l10/design.json\n"
        "exit codes: 0 the target is reached (>= --require of the verification's and as many fresh noise seeds), "
        "2 bad input, 3 not reached "
        "(design.json names the nearest reachable target).",
    )
    ap.add_argument("--target", required=True, help="lambda=N (cells; Z = 2(n-1)/N walls) or walls=A.5,B.5,...")
    ap.add_argument(
        "--push",
        default=None,
        help="CELL[:SIGN],... hand pushes on alpha, + CCW (default) or - CW (default: the scene's pushes)",
    )
    ap.add_argument(
        "--rest",
        default=None,
        metavar="CELLS",
        help="cells that must end at rest, e.g. 9-16; on a sheet rows=A-B, cols=A-B or A-BxC-D (joined by +)",
    )
    ap.add_argument(
        "--sheet",
        default=None,
        metavar="ROWSxCOLS",
        help="design on a square sheet (e.g. 16x16): --target pattern or lambda=N, --rest the region at rest, "
        "--push ROWxCOL[:SIGN],...",
    )
    ap.add_argument("--scene", default="default", help="scene giving everything not designed (default: default)")
    ap.add_argument("--vary", default="sigma,k_ab,k2", help="parameters the design may change (default sigma,k_ab,k2)")
    ap.add_argument(
        "--per-cell",
        default=None,
        help="of those, the ones that may differ between the target's domains (default: none for lambda=, "
        "sigma,k_ab,k2 for walls=; 'none' for none)",
    )
    ap.add_argument("--seeds", type=int, default=20, help="noise seeds of the verification (default 20)")
    ap.add_argument(
        "--search-seeds", type=int, default=None, help="noise seeds per candidate in the search (default 8; sheet 4)"
    )
    ap.add_argument("--maxiter", type=int, default=None, help="generations of the hil search (default 8; sheet 4)")
    ap.add_argument("--require", type=float, default=REQUIRE, help="fraction of seeds that must land (default 0.9)")
    ap.add_argument("--no-nearest", action="store_true", help="do not look for the nearest reachable target")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler address: the hil ensembles run there")
    ap.add_argument("--out", default=None, help="output directory (default out/design_<target>)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines")
    args = ap.parse_args(argv)
    per = None if args.per_cell is None else (() if args.per_cell == "none" else tuple(args.per_cell.split(",")))
    out = args.out or "out/design_" + args.target.replace("=", "_").replace(",", "_")
    if args.sheet:
        return _sheet_main(args, out)
    try:
        doc = design(
            args.target,
            args.push,
            scene=args.scene,
            vary=tuple(v.strip() for v in args.vary.split(",") if v.strip()),
            per_cell=per,
            rest=args.rest,
            seeds=args.seeds,
            search_seeds=8 if args.search_seeds is None else args.search_seeds,
            maxiter=8 if args.maxiter is None else args.maxiter,
            require=args.require,
            nearest=not args.no_nearest,
            out=out,
            scheduler=args.scheduler,
            quiet=args.quiet,
        )
    except DesignError as e:
        print(f"design: error: {e}", file=sys.stderr)
        return 2
    v, c = doc["verification"], doc["cross_check"]
    print(
        f"design {doc['target']} (push {doc['push_text']}): lands in {100 * v['fraction_seeds']:.0f} % of "
        f"{v['seeds']} noise seeds and {100 * (v['fraction_pushes'] or 0):.0f} % of "
        f"{len(v['push_torques_Nm']) * len(v['push_durations_s'])} pushes (hil, scene.toml as run loads it; each "
        f"seed a draw of the rig's uncertainty), {100 * c['fraction_seeds']:.0f} % of the same seeds in "
        f"{c['model']}; {doc['search']['hil_runs']} runs, {doc['search']['wall_s']:.0f} s"
    )
    fw = doc["assumes"]["firmware"]
    print(
        f"  assumes: back-EMF compensation {'on' if fw['bemf_comp'] else 'off'}, PWM limit {fw['pwm_limit_ticks']} "
        f"of {fw['pwm_top']} ticks, control rate {fw['control_rate_hz']:g} Hz, stepper "
        f"{doc['assumes']['model_options']['stepper']}"
    )
    if c["fraction_seeds"] < doc["require"] <= v["fraction_seeds"] and not fw["bemf_comp"]:
        print(
            f"  note: without the motors' back-EMF damping ({c['model']}) it lands in "
            f"{100 * c['fraction_seeds']:.0f} %: keep back-EMF compensation off on the rig (command apply checks it)"
        )
    for k in doc["vary"]:
        val = doc["params"][k]
        print(f"  {k}: " + (" ".join(f"{x:.4g}" for x in val) if isinstance(val, list) else f"{val:.6g}"))
    conf = doc["confirmation"]
    print(
        f"  confirmation on {conf['seeds']} fresh seeds: {100 * conf['fraction_seeds']:.0f} % land; "
        f"{100 * conf['pooled']:.1f} % of all {2 * conf['seeds']}"
    )
    if not doc["reached"]:
        near = doc["nearest_reachable"]
        print(
            f"NOT REACHED: below {100 * doc['require']:.0f} % of the verification's and the confirmation's seeds"
            "; nearest reachable: "
            + (f"{near['target']} ({100 * near['fraction_seeds']:.0f} %)" if near else "none found nearby")
        )
    print(f"wrote {out}/design.json, scene.toml, design.png")
    return 0 if doc["reached"] else 3


def _sheet_main(args: argparse.Namespace, out: str) -> int:
    """`design --sheet ROWSxCOLS`: design_sheet and its report."""
    from .sheet_driver import design_sheet

    for flag, given in (("--scheduler", args.scheduler), ("--per-cell", args.per_cell)):
        if given is not None:  # a sheet's ensembles run in this process; every varied parameter is per region
            print(f"design: error: {flag} is for a chain's design, not with --sheet", file=sys.stderr)
            return 2
    try:
        doc = design_sheet(
            args.target,
            args.push,
            sheet=args.sheet,
            rest=args.rest,
            scene=args.scene,
            vary=tuple(v.strip() for v in args.vary.split(",") if v.strip()),
            seeds=args.seeds,
            search_seeds=4 if args.search_seeds is None else args.search_seeds,
            maxiter=4 if args.maxiter is None else args.maxiter,
            require=args.require,
            out=out,
            quiet=args.quiet,
        )
    except DesignError as e:
        print(f"design: error: {e}", file=sys.stderr)
        return 2
    v, c, conf = doc["verification"], doc["cross_check"], doc["confirmation"]
    print(
        f"design {doc['target']} on a {doc['sheet'][0]} x {doc['sheet'][1]} sheet (push {doc['push_text']}): lands "
        f"in {100 * v['fraction_seeds']:.0f} % of {v['seeds']} noise seeds and {100 * (v['fraction_pushes'] or 0):.0f} "
        f"% of {len(v['push_torques_Nm']) * len(v['push_durations_s'])} pushes (hil), "
        f"{100 * c['fraction_seeds']:.0f} % of the same seeds in {c['model']}; {doc['search']['hil_runs']} runs, "
        f"{doc['search']['wall_s']:.0f} s"
    )
    for region in ("pattern", "rest"):
        law = doc["regions"][region]
        print(f"  {region} region: " + ", ".join(f"{k} {law[k]:.6g}" for k in doc["vary"]))
    print(
        f"  confirmation on {conf['seeds']} fresh seeds: {100 * conf['fraction_seeds']:.0f} % land; "
        f"{100 * conf['pooled']:.1f} % of all {2 * conf['seeds']}"
    )
    if not doc["reached"]:
        print(f"NOT REACHED: below {100 * doc['require']:.0f} % of the verification's and the confirmation's seeds")
    print(f"wrote {out}/design.json, scene.toml, design.png")
    return 0 if doc["reached"] else 3
