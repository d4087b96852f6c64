"""`python -m host_emulator dispersion`: linear stability of the rest state for given parameters, as JSON or a table."""

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
        "  python -m host_emulator dispersion --band-scale 0.5 --plot out/dispersion.png",
    )
    ap.add_argument("--sigma", type=str, default=None, help="feedback gain sigma, N m/rad (e.g. 0.072 or 9/125)")
    ap.add_argument(
        "--model",
        choices=("lattice", "hil", "continuum"),
        default="lattice",
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
        p = Params()
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
        theory = theory_of(args.model, p)
        if args.model == "continuum":
            theory = dataclasses.replace(theory, inertia=False)
        if args.inertia is not None:
            theory = dataclasses.replace(theory, inertia=args.inertia)
        if args.discrete is not None:
            theory = dataclasses.replace(theory, discrete=args.discrete)
        res = dispersion(p, theory=theory, n_cells=args.cells)
    except (ValueError, KeyError, FloatingPointError) as e:
        print(f"dispersion: error: {e.args[0] if e.args else e}", file=sys.stderr)
        return 2
    if args.plot:
        from ..workbench.plots import plot_dispersion_png

        plot_dispersion_png(p, args.plot, theory=theory)
        print(f"wrote {args.plot}", file=sys.stderr)
    if not args.curve:
        res.pop("curve")
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
    w = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(dispersion_main(sys.argv[1:]))
