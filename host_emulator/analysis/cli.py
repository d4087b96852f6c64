"""`python -m host_emulator dispersion`: linear stability of the rest state for given parameters (a chain, or a sheet's
annulus with --sheet or a sheet scene), as JSON or a table."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Iterable
from typing import Any

from host_emulator.params import Params

from .stability import REGIMES, dispersion, format_set, theory_of

__all__ = ["dispersion_main", "parse_set"]


def parse_set(params: Params, items: Iterable[str]) -> Params:
    """Apply KEY=VALUE overrides (Params field names) with the field's type; ValueError/KeyError on bad input."""
    fields = {f.name: f for f in dataclasses.fields(params)}
    kw: dict[str, Any] = {}
    for item in items or []:
        if "=" not in item:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE")
        key, val = (s.strip() for s in item.split("=", 1))
        key = key.removeprefix("params.")
        if key not in fields:
            raise KeyError(f"--set {key}: unknown parameter; known: {', '.join(sorted(fields))}")
        cur = getattr(params, key)
        if isinstance(cur, bool):
            low = val.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError(f"--set {key}={val!r}: expected true/false")
            kw[key] = low in ("true", "1", "yes")
        elif isinstance(cur, int):
            kw[key] = int(val)
        else:
            kw[key] = _number(val, key)
    return params.with_overrides(**kw)


def _number(text, what):
    """A float, also accepting a simple fraction such as 9/125."""
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            v = float(num) / float(den)
        else:
            v = float(text)
    except (ValueError, ZeroDivisionError):
        raise ValueError(f"{what}={text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{what}={text!r} must be finite")
    return v


def _fmt(v, unit=""):
    if v is None:
        return "-"
    if isinstance(v, list):
        return "[" + ", ".join("inf" if x is None else f"{x:.3f}" for x in v) + "]" + unit
    if isinstance(v, float):
        return f"{v:.4g}{unit}"
    return str(v)


def dispersion_main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator dispersion",
        description="Linear stability of the uniform rest state (docs/physics.md#linear-stability).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator dispersion --sigma 9/125\n"
        "  python -m host_emulator dispersion --sigma 12/125 --band-scale 0.5 --json   # two unstable intervals\n"
        "  python -m host_emulator dispersion --sigma 14/125 --model hil                # the hil model: rest\n"
        "  python -m host_emulator dispersion --sigma 9/125 --no-inertia --cells 16    # the source's theory\n"
        "  python -m host_emulator dispersion --band-scale 0.5 --plot out/dispersion.png\n"
        "  python -m host_emulator dispersion --sigma 9/125 --sheet 16x16 --boundary periodic  # the 2-D annulus\n"
        "  python -m host_emulator dispersion --scene default                                # a scene's theory",
    )
    ap.add_argument("--sigma", type=str, default=None, help="feedback gain sigma, N m/rad (e.g. 0.072 or 9/125)")
    ap.add_argument(
        "--scene",
        default=None,
        metavar="SCENE",
        help="start from a scene's parameters, lattice and model (shipped name or .toml); a sheet scene prints "
        "its annulus (docs/sheets.md)",
    )
    ap.add_argument(
        "--sheet",
        default=None,
        metavar="ROWSxCOLS",
        help="the 2-D theory of a sheet of ROWS x COLS cells (e.g. 16x16): its unstable annulus, fastest "
        "wavevectors and which of the finite sheet's modes grow (docs/sheets.md)",
    )
    ap.add_argument("--lattice", choices=("square", "hex"), default=None, help="the sheet's lattice (default square)")
    ap.add_argument("--boundary", choices=("open", "periodic"), default=None, help="the sheet's edges (default open)")
    ap.add_argument(
        "--model",
        choices=("lattice", "hil", "continuum"),
        default=None,
        help="whose linear theory: lattice (default; with inertia), hil (the lattice plus the motors' back-EMF "
        "damping, 15/16 of it removed with --set bemf_comp=true) or continuum (kappa^2, no inertia), as the "
        "run summaries of those models",
    )
    g = ap.add_mutually_exclusive_group()
    g.add_argument(
        "--inertia",
        dest="inertia",
        action="store_true",
        default=None,
        help="include cylinder inertia (4 roots per mode; the default except for --model continuum)",
    )
    g.add_argument(
        "--no-inertia",
        dest="inertia",
        action="store_false",
        help="drop inertia: the overdamped theory of the source's stability figure",
    )
    ap.add_argument("--eta-scale", type=str, default=None, help="multiply both viscous coefficients")
    ap.add_argument(
        "--band-scale",
        type=str,
        default=None,
        help="band-law scale (effective stiffness 2 x band_scale x table k): 1.0 = the rig's pair of "
        "bands, the default of every scene; 0.5 = the table k of the source's stability figure",
    )
    g = ap.add_mutually_exclusive_group()
    g.add_argument(
        "--discrete",
        dest="discrete",
        action="store_true",
        default=None,
        help="lattice dispersion, kappa^2 -> 2(1 - cos kappa) (the default but for --model continuum)",
    )
    g.add_argument("--continuum", dest="discrete", action="store_false", help="continuum dispersion (kappa^2)")
    ap.add_argument("--cells", type=int, default=None, help="also list the modes of a free-end chain of N cells")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a Params field")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--curve", action="store_true", help="include the sampled curve in the JSON")
    ap.add_argument(
        "--plot",
        default=None,
        metavar="PNG",
        help="also draw the dispersion (lattice and continuum, band, fastest wavelength) to PNG",
    )
    args = ap.parse_args(argv)
    if args.plot:
        from ..outpaths import check_out_file

        problem = check_out_file(args.plot, "--plot")
        if problem:
            print(f"dispersion: error: {problem}", file=sys.stderr)
            return 2
    try:
        p, model, inertia = Params(), "lattice", True
        if args.scene is not None:
            from ..scene import load_scene

            scene = load_scene(args.scene)
            p, model, inertia = scene.params, scene.model, scene.options.inertia
        if args.model is not None:
            model = args.model
        p = _sheet_params(p, args)
        if args.sigma is not None:
            p = p.with_overrides(sigma=_number(args.sigma, "--sigma"))
        if args.eta_scale is not None:
            p = p.with_overrides(eta_scale=_number(args.eta_scale, "--eta-scale"))
        if args.band_scale is not None:
            bs = _number(args.band_scale, "--band-scale")
            if not bs > 0:
                raise ValueError(f"--band-scale={args.band_scale}: must be > 0")
            p = p.with_overrides(band_scale=bs)
        p = parse_set(p, args.set)
        if args.cells is not None and args.cells < 1:
            raise ValueError("--cells must be >= 1")
        theory = theory_of(model, p, inertia)
        if model == "continuum":
            theory = dataclasses.replace(theory, inertia=False)
        if args.inertia is not None:
            theory = dataclasses.replace(theory, inertia=args.inertia)
        if args.discrete is not None:
            theory = dataclasses.replace(theory, discrete=args.discrete)
        sheet = _sheet_result(p, theory) if p.topology.is_sheet else None
        res = dispersion(p.uniform(), theory=theory, n_cells=args.cells)
    except (ValueError, KeyError, FloatingPointError) as e:
        print(f"dispersion: error: {e.args[0] if e.args else e}", file=sys.stderr)
        return 2
    if args.plot:
        from ..workbench.plots import plot_dispersion_png

        plot_dispersion_png(p, args.plot, theory=theory)
        print(f"wrote {args.plot}", file=sys.stderr)
    if not args.curve:
        res.pop("curve")
    if sheet is not None:
        res["sheet"] = sheet
    if args.json:
        print(json.dumps(res, indent=2, allow_nan=False))
        return 0
    print(
        f"sigma = {p.sigma:.6g} N m/rad, eta_scale = {p.eta_scale:g}, gamma = {p.gamma:g}, "
        f"band_scale = {p.band_scale:g} (k_a = {p.ka_eff:.4g}, k_b = {p.kb_eff:.4g} N m/rad)"
    )
    print(f"linear theory: {res['theory']}")
    rows = [
        ("regime", f"{res['regime']} ({REGIMES[res['regime']]})"),
        ("unstable set", format_set(res["unstable_set_cells"]) + (" cells" if res["unstable_set_cells"] else "")),
    ]
    for iv in res["unstable_intervals"]:
        lo, hi = iv["lambda_cells"]
        rows.append(
            (
                f"  {lo:.2f}-{'inf' if hi is None else format(hi, '.2f')} cells",
                f"{iv['kind']}, fastest "
                + (_fmt(iv["fastest_lambda_cells"], " cells") if iv["fastest_lambda_cells"] else "uniform")
                + f" at {iv['fastest_growth_per_s']:.4g} 1/s"
                + (f", period {iv['period_s']:.4g} s" if iv["period_s"] else ""),
            )
        )
    rows += [
        (
            "fastest wavelength",
            _fmt(res["fastest_lambda_cells"], " cells") if res["fastest_lambda_cells"] else "uniform (inf)",
        ),
        ("fastest growth rate", _fmt(res["fastest_growth_per_s"], " 1/s")),
        ("oscillation period", _fmt(res["oscillation_period_s"], " s")),
        ("uniform mode growth", _fmt(res["uniform_mode_growth_per_s"], " 1/s")),
        ("uniform mode period", _fmt(res["uniform_mode_period_s"], " s")),
        (
            "Turing conditions",
            "all hold"
            if res["turing"]["all"]
            else "fail: " + ", ".join(k for k, v in res["turing"].items() if k != "all" and not v["holds"]),
        ),
    ]
    if "lattice_fastest_mode" in res:
        m = res["lattice_fastest_mode"]
        rows.append(
            (
                f"fastest of {args.cells} cells",
                f"m={m['m']} lambda={_fmt(m['lambda_cells']) if m['lambda_cells'] else 'inf (uniform)'} "
                f"growth={m['growth_per_s']:.4g} 1/s",
            )
        )
    if sheet is not None:
        rows += _sheet_rows(sheet)
    w = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")
    return 0


def _sheet_params(p: Params, args) -> Params:
    """The parameters with --sheet/--lattice/--boundary applied (ValueError on a bad ROWSxCOLS)."""
    if args.sheet is None:
        if args.lattice or args.boundary:
            if not p.topology.is_sheet:
                raise ValueError("--lattice and --boundary need --sheet ROWSxCOLS (or a sheet scene)")
            return p.with_overrides(lattice=args.lattice or p.lattice, boundary=args.boundary or p.boundary)
        return p
    parts = args.sheet.lower().split("x")
    if len(parts) != 2 or not all(t.strip().isdigit() and int(t) >= 1 for t in parts):
        raise ValueError(f"--sheet {args.sheet!r}: expected ROWSxCOLS, e.g. 16x16")
    rows, cols = (int(t) for t in parts)
    if p.per_cell_keys:
        raise ValueError("--sheet: the parameters give one value per cell; set them without per-cell values")
    q = p.with_overrides(
        cells=rows * cols,
        shape=(rows, cols),
        lattice=args.lattice or (p.lattice if p.lattice != "chain" else "square"),
        boundary=args.boundary or "open",
    )
    q.topology  # noqa: B018 - raises TopologyError (a ValueError) on a sheet that cannot be built
    return q


def _sheet_result(p: Params, theory) -> dict:
    """The sheet's 2-D theory for the JSON: annulus, fastest wavevectors, the finite sheet's growing modes."""
    from .sheet import annulus, fastest, finite_sheet

    fs = finite_sheet(p, theory)
    grow = [{k: v for k, v in m.items() if k != "unstable"} for m in fs["modes"] if m["unstable"]]
    return {
        "topology": fs["topology"],
        "annulus": annulus(p, theory),
        "fastest": fastest(p, theory),
        "finite_sheet": {
            "unstable_modes": grow,
            "fastest_mode": {k: v for k, v in fs["fastest_mode"].items() if k != "unstable"},
            "relative_to_fastest": fs["relative_to_fastest"],
            "in_annulus": fs["in_annulus"],
        },
    }


def _pair(v, unit=" cells") -> str:
    if v is None:
        return "-"
    lo, hi = v
    return f"{lo:.3f}-{'inf' if hi is None else format(hi, '.3f')}{unit}"


def _sheet_rows(sheet: dict) -> list[tuple[str, str]]:
    """The table rows of the sheet's 2-D theory."""
    an, fa, fs = sheet["annulus"], sheet["fastest"], sheet["finite_sheet"]
    rows = [("sheet", f"{sheet['topology']}: the 2-D theory (docs/sheets.md)")]
    for iv in an["intervals"]:
        rows.append((f"  annulus ({iv['kind']})", f"continuum {_pair(iv['continuum']['lambda_cells'])}"))
        for name, ext in iv["discrete"].items():
            edge = " (to the zone edge)" if ext["to_zone_edge"] else ""
            rows.append((f"    lattice, {name}", _pair(ext["lambda_cells"]) + edge))
    if not an["intervals"]:
        rows.append(("  annulus", "none (no wavevector grows)"))
    if fa["q"] > 0:
        disc = ", ".join(
            f"{name} {_fmt(d['lambda_cells'], ' cells')}" for name, d in fa["discrete"].items() if name != "corner"
        )
        rows.append(
            (
                "  fastest wavelength",
                f"continuum {_fmt(fa['continuum']['lambda_cells'], ' cells')}; lattice {disc} "
                f"at {fa['growth_per_s']:.4g} 1/s",
            )
        )
    else:
        rows.append(("  fastest wavelength", f"uniform (inf) at {fa['growth_per_s']:.4g} 1/s"))
    m = fs["fastest_mode"]
    rel = fs["relative_to_fastest"]
    k = "-" if m["k"] is None else f"[{m['k'][0]:.4f}, {m['k'][1]:.4f}] rad/cell"
    rows.append(
        (
            "  fastest sheet mode",
            f"k={k} lambda={_fmt(m['lambda_cells'], ' cells') if m['lambda_cells'] else 'inf (uniform)'} "
            f"growth={m['growth_per_s']:.4g} 1/s"
            + (f", {100 * rel:+.1f}% of the fastest wavelength" if rel is not None else "")
            + ("" if fs["in_annulus"] else " (decays: nothing on this sheet grows)"),
        )
    )
    rows.append(("  growing sheet modes", str(len(fs["unstable_modes"]))))
    return rows


if __name__ == "__main__":  # pragma: no cover
    sys.exit(dispersion_main(sys.argv[1:]))
