"""Command line: `python -m host_emulator scenes | run SCENE | plot PATH | runs DIR | dispersion ... | bench ...`."""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from metacell_common.cli import unexpected
from metacell_common.outpaths import created_mark, remove_created_since

from .firmware import FirmwareBuildError
from .outpaths import check_out_file

if TYPE_CHECKING:
    from .workbench.trackers import PlotTracker, Tracker


def cmd_scenes(args: argparse.Namespace) -> int:
    from .scene import list_scenes

    for name, model, desc in list_scenes():
        print(f"{name:22s} {model:9s} {desc}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .analysis.summary import summarize
    from .controller import run_scene
    from .models import ConfigError, NumericalInstability
    from .scene import load_scene
    from .workbench.plots import plot_run

    try:
        extra = [f"accuracy={args.accuracy}"] if args.accuracy else []
        scene = load_scene(args.scene, list(args.set) + extra + ([f"model={args.model}"] if args.model else []))
    except (ConfigError, KeyError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from .limits import check_out_dir, check_run

    out = Path(args.out or Path("out") / scene.name)
    problem = (
        check_run(scene)
        or check_out_dir(out)
        or (check_out_file(args.live_png, "--live-png") if args.live_png else None)
    )
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    if scene.model_reason:
        print(scene.model_reason)
    try:
        live, plot = _live_trackers(args, scene, out)
        res = run_scene(scene, progress=not args.quiet, trackers=live)
    except NumericalInstability as e:
        print(f"error: run stopped: {e}", file=sys.stderr)
        return 3
    except (ConfigError, ValueError, OverflowError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except MemoryError as e:
        print(f"error: run failed: out of memory ({e})", file=sys.stderr)
        return 3
    summary = summarize(scene, res)
    from .workbench.datasets import write_run

    write_run(out / "trajectories.npz", scene, res.t, res.alpha, res.beta, summary, summary["source"])
    files = [] if args.no_plots else plot_run(res, scene, out, fmt=args.format, column=args.column)
    summary["files"] = ["summary.json", "trajectories.npz"] + [f.name for f in files]
    (out / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    _print_summary(summary, out, files, scene.topology)
    if plot is not None and plot.interactive:
        from matplotlib import pyplot as plt

        print("live plot: close its window to exit", file=sys.stderr)
        plt.show()
    return 0


def _live_trackers(args, scene, out: Path) -> tuple[list[Tracker], PlotTracker | None]:
    """Trackers for --print-every and --live; the PlotTracker (or None). On a non-interactive matplotlib
    backend the live figure goes to --live-png (default OUT/live.png), said once on stderr."""
    from .workbench.trackers import LiveTracker, PlotTracker

    live: list[Tracker] = [LiveTracker(args.print_every)] if args.print_every else []
    plot: PlotTracker | None = None
    if args.live is not None:
        plot = PlotTracker(args.live, args.live_window, png=args.live_png, title=scene.name)
        plot.setup(scene.cells, scene.t_end_s)  # opens the window before the run starts
        if not plot.interactive and plot.png is None:
            plot.png = str(out / "live.png")
        if plot.png:
            print(f"live plot: {plot.png} is rewritten every {args.live:g} ms of simulated time", file=sys.stderr)
        live.append(plot)
    return live, plot


def _fmt(v, unit="", nd=4):
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:.{nd}g}{unit}"
    return f"{v}{unit}"


def _bonds(bonds) -> str:
    """' at 4.5, 9.5' (the walls' bonds j + 0.5), or '' without walls."""
    return " at " + ", ".join(f"{b:g}" for b in bonds) if bonds else ""


def _print_summary(s, out, files, topology=None):
    """The run's printout. A lattice other than the open chain says which (Topology.describe()); a 2-D sheet
    prints its pattern measures where the summary has them (dominant_wavelength_cells, pattern_kind) instead of the
    chain's walls and profile."""
    d = s.get("dispersion") or {}
    sheet = topology is not None and topology.is_sheet
    print(
        f"scene {s['scene']} ({s['model']}): {s['t_end_s']:.3g} s simulated in {s['wall_s']:.3g} s "
        f"wall ({s['realtime_factor']:.{0 if s['realtime_factor'] >= 10 else 2}f}x real time)"
    )
    if topology is not None and not topology.is_open_chain:
        print(f"  lattice: {topology.describe()}")
    for note in (s.get("solver") or {}).get("adjusted", ()):  # options the model could not take as given
        print(f"  adjusted: {note}")
    if sheet:
        _print_sheet(s)
    else:
        _print_chain(s)
    _print_theory(s, d, out, files)


def _print_sheet(s) -> None:
    """A sheet's lines: steady, at rest, amplitude; the 2-D pattern measures the summary holds; alpha's range."""
    print(
        f"  steady: {s.get('steady')}   at rest: {s.get('at_rest')}   "
        f"oscillation period: {_fmt(s.get('oscillation_period_s'), ' s')}   "
        f"amplitude: {_fmt(s.get('amplitude_rad'), ' rad')}"
    )
    parts = []
    if "pattern_kind" in s:
        parts.append(f"pattern: {_fmt(s['pattern_kind'])}")
    if "dominant_wavelength_cells" in s:
        parts.append(f"dominant wavelength: {_fmt(s['dominant_wavelength_cells'], ' cells')}")
    if parts:
        print("  " + "   ".join(parts))
    fa = [v for v in s.get("final_alpha_rad") or [] if v is not None]
    if fa:
        print(f"  final alpha (rad): {min(fa):+.2f} .. {max(fa):+.2f} over {len(s['final_alpha_rad'])} cells")


def _print_chain(s) -> None:
    print(
        f"  steady: {s['steady']}   pattern period: {_fmt(s['pattern_period_cells'], ' cells')}   "
        f"oscillation period: {_fmt(s['oscillation_period_s'], ' s')}   amplitude: {_fmt(s['amplitude_rad'], ' rad')}"
    )
    print(
        f"  at rest: {s['at_rest']}   domain walls: {s['domain_walls']}{_bonds(s.get('domain_wall_bonds'))}   "
        f"wavelength 2(N-1)/Z: {_fmt(s['pattern_wavelength_cells'], ' cells')}   "
        f"dominant mode: {_fmt(s['dominant_mode'])} ({_fmt(s['dominant_mode_lambda_cells'], ' cells')})"
    )
    print("  final alpha (rad): " + " ".join(f"{v:+.2f}" for v in s["final_alpha_rad"]))


def _print_theory(s, d, out, files) -> None:
    if d:
        from .analysis.stability import format_set

        print(f"  linear theory ({d.get('theory')}): {d.get('regime')}")
        print(
            (
                f"    unstable wavelengths {format_set(d['unstable_set_cells'])} cells, fastest "
                if d.get("unstable_set_cells")
                else "    nothing grows; least stable: "
            )
            + (_fmt(d["fastest_lambda_cells"], " cells") if d.get("fastest_lambda_cells") else "the uniform mode")
            + f" at {_fmt(d.get('fastest_growth_per_s'), '/s')}"
            + (f", period {_fmt(d['oscillation_period_s'], ' s')}" if d.get("oscillation_period_s") else "")
        )
    if s.get("accuracy"):
        from .accuracy import estimate_line

        print(estimate_line(s["accuracy"]))
    print(
        f"  wrote {out}/summary.json, trajectories.npz"
        + ("" if not files else ", plots: " + ", ".join(str(f) for f in files))
    )


def _model_names() -> tuple[str, ...]:
    from .models import model_names

    return model_names()


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def cmd_bench(args) -> int:
    from .benchmarks.speed import bench_main

    return bench_main(args.rest)


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 ok, 2 bad input (values, paths; an output directory made for it is removed again), 3 the run
    failed."""
    mark = created_mark()
    rc = _guarded(argv)
    if rc == 2:
        remove_created_since(mark)  # a rejection leaves nothing behind
    return rc


def _guarded(argv: list[str] | None) -> int:
    try:
        return _main(argv)
    except FirmwareBuildError as e:  # no sources, no compiler: say what is missing, not a traceback
        print(f"error: {e}", file=sys.stderr)
        return 3
    except BrokenPipeError:  # e.g. `dispersion --json | head`: the reader left, not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 3
    except Exception as e:  # noqa: BLE001 - the last guard: one line, never a traceback (MC_DEBUG=1 shows it)
        return unexpected(e, "host_emulator")


# subcommands with their own argument parsers: name -> (module, entry point), imported only when used
SUBCOMMANDS = {
    "dispersion": (".analysis.cli", "dispersion_main"),
    "serve": (".bus.serve", "serve_main"),
    "bench-speed": (".benchmarks.speed", "bench_main"),
    "robustness": (".workbench.robustness", "robustness_main"),
    "paper": (".workbench.paper", "paper_main"),
    "animate": (".workbench.animate", "animate_main"),
    "sweep": (".workbench.sweep", "sweep_main"),
    "design": (".workbench.design", "design_main"),
    "bench": (".benchmarks.cli", "main"),
    "image": (".image.cli", "image_main"),
    "boards": (".image.boards", "boards_main"),
    "plot": (".workbench.figures", "plot_main"),
    "runs": (".workbench.catalogue", "runs_main"),
}


def _main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in SUBCOMMANDS:
        module, func = SUBCOMMANDS[argv[0]]
        return getattr(importlib.import_module(module, __package__), func)(argv[1:])
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator",
        description="Host emulator of the robotic metamaterial (docs/physics.md).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator scenes\n"
        "  python -m host_emulator run default --out out/default\n"
        "  python -m host_emulator run exp3_single_sigma6 --set params.sigma=6/125 --live\n"
        "  python -m host_emulator dispersion --sigma 9/125 --inertia\n"
        "  python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 --out out/sweep\n"
        "  python -m host_emulator SUBCOMMAND --help       # the options of one subcommand\n"
        "exit codes: 0 ok, 2 bad input (values, paths), 3 the run failed.",
    )
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="SUBCOMMAND", help="what to do")
    sub.add_parser(
        "scenes",
        help="list the shipped scenes",
        description="List the shipped scenes: name, model, description.",
        epilog="example: python -m host_emulator scenes",
    )
    r = sub.add_parser(
        "run",
        help="run a scene (shipped name or .toml path)",
        description="Run a scene: summary.json, trajectories.npz and plots in --out.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator run default\n"
        "  python -m host_emulator run exp1_ccw_ccw --set t_end_s=5 --out out/exp1 --no-plots\n"
        "  python -m host_emulator run default --live 50 --live-window 3    # live plot every 50 ms\n"
        "  python -m host_emulator run my_scene.toml --accuracy exact --print-every 1\n"
        "  python -m host_emulator run exp3_single_sigma9 --model auto    # the cheapest tier for its question\n"
        "exit codes: 0 ok, 2 bad input (values, paths), 3 the run failed.",
    )
    r.add_argument("scene", help="shipped scene name (see `scenes`) or path of a .toml scene file")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene key, e.g. params.sigma=0.048, model_options.inertia=false, t_end_s=5",
    )
    r.add_argument("--out", default=None, help="output directory (default out/<scene>)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument(
        "--live",
        type=_positive_float,
        nargs="?",
        const=100.0,
        default=None,
        metavar="MS",
        help="live plot (rolling space-time map of alpha, current alpha/beta profile) redrawn every MS of "
        "simulated time (default 100); a window on an interactive matplotlib backend, else --live-png",
    )
    r.add_argument(
        "--live-window",
        type=_positive_float,
        default=2.0,
        metavar="S",
        help="seconds of simulated time the live space-time map shows (default 2)",
    )
    r.add_argument(
        "--live-png",
        default=None,
        metavar="PNG",
        help="also rewrite the live figure to this file at every redraw (default on a non-interactive backend, "
        "e.g. MPLBACKEND=Agg or no display: OUT/live.png)",
    )
    r.add_argument(
        "--print-every",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="print max |alpha|, |beta| every SECONDS of simulated time",
    )
    r.add_argument("--no-plots", action="store_true", help="skip the plots")
    r.add_argument(
        "--format",
        choices=("png", "pdf", "svg"),
        default="png",
        help="the plots' file format (default png; pdf and svg for a paper)",
    )
    r.add_argument("--column", action="store_true", help="plots one paper column wide (3.4 in), fonts to match")
    r.add_argument(
        "--accuracy",
        choices=("fast", "balanced", "exact"),
        default=None,
        help="stepper/step/model fidelity preset (default: the scene's, else balanced; docs/accuracy.md)",
    )
    r.add_argument(
        "--model",
        choices=(*_model_names(), "auto"),
        default=None,
        help="run this model instead of the scene's; auto: the cheapest tier that models the scene's `question` "
        "(pattern, oscillation, growth, continuum, bus, timing, faults), said in one line (docs/accuracy.md#tiers)",
    )
    sub.add_parser(
        "plot",
        help="figures of a run or capture as PNG, PDF or SVG (see plot --help)",
        epilog="example: python -m host_emulator plot --help",
    )
    sub.add_parser(
        "runs",
        help="a catalogue of the runs and captures under a folder (see runs --help)",
        epilog="example: python -m host_emulator runs --help",
    )
    sub.add_parser(
        "dispersion",
        help="linear stability (see dispersion --help)",
        epilog="example: python -m host_emulator dispersion --help",
    )
    sub.add_parser(
        "robustness",
        help="fraction of noise seeds and pushes selecting the source's result (see robustness --help)",
        epilog="example: python -m host_emulator robustness --help",
    )
    sub.add_parser(
        "paper",
        help="regenerate the source paper's Fig. 2 and 3, item by item (see paper --help)",
        epilog="example: python -m host_emulator paper --help",
    )
    sub.add_parser(
        "animate",
        help="GIF/MP4 of the lattice forming its pattern (see animate --help)",
        epilog="example: python -m host_emulator animate --help",
    )
    sub.add_parser(
        "sweep",
        help="a grid of overrides x seeds on Dask into one xarray dataset (see sweep --help)",
        epilog="example: python -m host_emulator sweep --help",
    )
    sub.add_parser(
        "serve",
        help="emulated primary as an SLCAN device on a pty (see serve --help)",
        epilog="example: python -m host_emulator serve --help",
    )
    sub.add_parser(
        "bench-speed",
        help="real-time factor of the default hil scene (see bench-speed --help)",
        epilog="example: python -m host_emulator bench-speed --help",
    )
    sub.add_parser(
        "bench",
        help="work-precision vs scipy/py-pde, scaling, --fidelity (see bench --help)",
        epilog="example: python -m host_emulator bench --help",
    )
    sub.add_parser(
        "image",
        help="the flashed images: build, registers each touches, cycle profile (see image --help)",
        epilog="example: python -m host_emulator image --help",
    )
    sub.add_parser(
        "boards",
        help="the flashed images as USB boards on ptys with a port listing, for the flash tool (see boards --help)",
        epilog="example: python -m host_emulator boards --help",
    )
    args = ap.parse_args(argv)
    return {"scenes": cmd_scenes, "run": cmd_run}[args.cmd](args)
