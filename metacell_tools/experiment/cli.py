"""Command line: `python -m metacell_tools.experiment run SCENE --channel PORT@BAUD | rehearse SCENE |
compare RIG_DIR EMU_DIR`.

Exit status: 0 done cleanly, 1 done with problems (failed commands under --keep-going,
missing cells, lost samples, a cell whose drive-off was not confirmed, a cell reporting
another protocol map id: all in the summary), 2 bad scene/argument (nothing sent to the rig),
3 aborted (failed command, lost link; the drive was switched off if the link allowed),
130 interrupted by Ctrl-C (drive switched off first).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from host_emulator.scene import Scene

    from .plan import ExperimentPlan
    from .runner import Options

LOG_FORMATS = ("asc", "blf", "csv", "db", "log", "trc", "txt", "mf4")
EXIT_OK, EXIT_PROBLEMS, EXIT_USAGE, EXIT_ABORTED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


def scene_arg(text: str) -> str:
    """A scene argument as load_scene takes it: a design (`python -m host_emulator design`'s directory or its
    design.json) means the scene.toml beside it; anything else is returned as given."""
    p = Path(text)
    if p.is_dir() and (p / "design.json").is_file():
        return str(p / "scene.toml")
    if p.name == "design.json" and p.is_file():
        return str(p.with_name("scene.toml"))
    return text


def _common(p: argparse.ArgumentParser):
    p.add_argument(
        "scene",
        type=scene_arg,
        help="shipped scene name or .toml path (as for python -m host_emulator run), or a design: its directory or "
        "design.json (python -m host_emulator design), whose scene.toml is run",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scene override, e.g. params.sigma=9/125, perturbation.1.torque_Nm=0.03, t_end_s=5",
    )
    p.add_argument(
        "--t-end", type=float, default=None, metavar="S", help="time limit per repeat (default: the scene's t_end_s)"
    )
    p.add_argument(
        "--rig",
        default=None,
        metavar="TOML",
        help="the rig config: how its cells are banded, e.g. cells = [4, 4] for a 4 x 4 sheet (default: rig/rig.toml "
        "when it exists, else the rig as built, a chain of 16); a sheet's scene runs and is analysed as that sheet",
    )
    p.add_argument("--repeats", type=int, default=1, help="repeats, re-zeroed in between (default 1)")
    p.add_argument(
        "--out", default=None, help="output directory (default out/rig/<scene>; a rehearsal: out/rehearsal/<scene>)"
    )
    p.add_argument(
        "--settle",
        type=float,
        default=1.0,
        metavar="S",
        help="stop a repeat once every cell moved < 2 counts for S seconds after the last push (default 1)",
    )
    p.add_argument("--no-early-stop", action="store_true", help="always run to the time limit")
    p.add_argument(
        "--relax",
        type=float,
        default=3.0,
        metavar="S",
        help="drive off this long between repeats before waiting for rest and zeroing (default 3)",
    )
    p.add_argument(
        "--rest-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="longest wait for the lattice to be still before zeroing (default 10)",
    )
    p.add_argument(
        "--keep-going",
        action="store_true",
        help="run on when a setup command fails on some cells (they stay disabled; all reported)",
    )
    p.add_argument("--timeout", type=float, default=1.0, help="seconds to wait for a command result (default 1)")
    p.add_argument("--silence", type=float, default=2.0, help="no frame for this long = link lost (default 2 s)")
    p.add_argument(
        "--pwm-limit",
        type=int,
        default=None,
        metavar="TICKS",
        help="PWM duty limit sent to the cells (default: from params.vmax_v; cells cap it at 5.86 V)",
    )
    p.add_argument("--formats", default="asc", help="python-can log formats, comma separated (default asc)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--live",
        type=_positive_float,
        nargs="?",
        const=200.0,
        default=None,
        metavar="MS",
        help="live plot of the running repeat (rolling space-time map of alpha, current profile) from the logged "
        "frames, redrawn every MS of primary-clock time (default 200); a window on an interactive matplotlib "
        "backend, else --live-png",
    )
    p.add_argument(
        "--live-window",
        type=_positive_float,
        default=2.0,
        metavar="S",
        help="seconds the live space-time map shows (default 2)",
    )
    p.add_argument(
        "--live-png",
        default=None,
        metavar="PNG",
        help="also rewrite the live figure to this file at every redraw (default on a non-interactive backend: "
        "OUT/live.png)",
    )
    p.add_argument(
        "--plain-slcan",
        action="store_true",
        help="python-can's own slcan reader (one system call per byte) instead of the buffered one",
    )


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def make_live(args, scene, out: Path, source: str = "rig"):
    """RigLive for --live (None without it, or when the renderer cannot start: said on stderr): the plot is drawn
    by its own process (liveview.LiveView), so the runner never waits for it; on a non-interactive matplotlib
    backend the figure goes to a PNG."""
    if getattr(args, "live", None) is None:
        return None
    from .live import RigLive
    from .liveview import LiveView

    view = LiveView(args.live, args.live_window)
    topology = getattr(scene, "topology", None)
    shape = topology.shape if topology is not None and topology.is_sheet else None
    live = RigLive(view, scene.cells, title=scene.name, source=source, shape=shape)
    live.begin(0, scene.t_end_s)  # the window opens before the bus does
    if not view.wait_started():
        print(f"live plot unavailable: {view.error}; running without it", file=sys.stderr)
        view.terminate()
        return None
    if args.live_png:
        view.set_png(args.live_png)
    elif not view.interactive:
        out.mkdir(parents=True, exist_ok=True)
        view.set_png(str(out / "live.png"))
    if view.png:
        print(f"live plot: {view.png} is rewritten every {args.live:g} ms of the run", file=sys.stderr)
    return live


def end_live(live) -> None:
    """Hand the renderer the last rows and let it finish: a PNG is complete when this returns; a window stays until
    it is closed (Ctrl-C closes it too)."""
    if live is None:
        return
    view = live.tracker
    view.close()
    if view.interactive and view.error is None:
        print("live plot: close its window to exit", file=sys.stderr)
        try:
            view.wait()
        except KeyboardInterrupt:
            view.terminate()
    elif view.wait(60) is None:
        view.terminate()
    if view.error and view.error != "the renderer exited":
        print(f"live plot: {view.error}", file=sys.stderr)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.experiment",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.experiment rehearse exp1_ccw_ccw --repeats 2   # no hardware: the emulator\n"
        "  python -m metacell_tools.experiment run exp1_ccw_ccw -c /dev/ttyACM0@115200 --repeats 3 --live\n"
        "  python -m metacell_tools.experiment compare out/rig/exp1_ccw_ccw out/exp1_ccw_ccw\n"
        "  python -m metacell_tools.experiment SUBCOMMAND --help\n" + __doc__.split("\n\n", 1)[1],
    )
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="SUBCOMMAND", help="what to do")
    r = sub.add_parser(
        "run",
        help="run a scene on the rig through the primary",
        description="Run a scene on the rig through the primary; summary.json, logs and plots in --out.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.experiment run exp1_ccw_ccw -c /dev/ttyACM0@115200\n"
        "  python -m metacell_tools.experiment run default -c /dev/ttyACM0@115200 --set params.sigma=6/125 --repeats 5 "
        "--live 100\n"
        "  python -m metacell_tools.experiment run exp5_rest -c /dev/ttyACM0@115200 --t-end 20 --no-early-stop "
        "--formats asc,blf",
    )
    _common(r)
    r.add_argument("--channel", "-c", required=True, help="python-can channel, e.g. /dev/ttyACM0@115200")
    r.add_argument("--interface", "-i", default="slcan", help="python-can interface (default slcan)")
    r.add_argument(
        "--open-wait",
        type=float,
        default=None,
        metavar="S",
        help="slcan: seconds python-can waits after opening the port (its default: 2)",
    )
    h = sub.add_parser(
        "rehearse",
        help="the same run against `python -m host_emulator serve` on a pty",
        description="The same run against the emulated primary (python -m host_emulator serve) on a pty.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.experiment rehearse exp1_ccw_ccw --set t_end_s=4 --repeats 2\n"
        "  python -m metacell_tools.experiment rehearse out/design_l10          # a design's scene.toml\n"
        "  python -m metacell_tools.experiment rehearse default --absent 3,7 --keep-going --live",
    )
    _common(h)
    for name in ("absent", "stuck", "babble"):
        h.add_argument(f"--{name}", default=None, metavar="CELLS", help=f"serve: {name} cells, e.g. 3,7")
    h.add_argument(
        "--serve-duration",
        type=float,
        default=None,
        metavar="S",
        help="serve stops after S simulated seconds (default: long enough for the run)",
    )
    c = sub.add_parser(
        "compare",
        help="overlay two runs of one scene, rig or emulated (any run directory, logger capture or python-can log)",
        description="Table and plot of the final angles of run A (markers, min..max over its repeats) against run B "
        "(lines). Each is anything host_emulator.load opens: an experiment or emulator run directory, a logger "
        "capture (NPZ/CSV) or a python-can log (ASC, BLF, ...).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.experiment compare out/rig/exp1_ccw_ccw out/exp1_ccw_ccw --out cmp.png\n"
        "  python -m metacell_tools.experiment compare run.asc out/default --source-a emulator:hil",
    )
    c.add_argument("a", metavar="A", help="first run: a directory with summary.json, a capture or a log")
    c.add_argument(
        "b", metavar="B", help="second run, the reference drawn as lines (e.g. `python -m host_emulator run`)"
    )
    c.add_argument("--out", default=None, help="PNG file (default A/compare.png, or beside A for a file)")
    for x in ("a", "b"):
        c.add_argument(
            f"--source-{x}",
            default=None,
            metavar="LABEL",
            help=f"label of {x.upper()} when its file does not say (a python-can log): rig, emulator:hil, ...",
        )
    return ap


def _prepare(args):
    """Scene and plan, or a message (exit 2) — before anything touches the rig."""
    from host_emulator.models import ConfigError
    from host_emulator.scene import load_scene

    from .plan import PlanError, make_plan
    from .rig import AS_BUILT, on_rig, rig_topology

    if args.repeats < 1:
        raise PlanError(f"--repeats {args.repeats}: expected >= 1")
    for name in ("settle", "relax", "rest_timeout", "timeout", "silence"):
        v = getattr(args, name)
        if not v > 0:
            raise PlanError(f"--{name.replace('_', '-')} {v}: expected > 0")
    try:
        scene = load_scene(args.scene, args.set)
    except (ConfigError, KeyError, ValueError, OSError) as e:
        raise PlanError(str(e).strip("'\"")) from None
    bad = [f for f in args.formats.split(",") if f.strip().lstrip(".") not in LOG_FORMATS]
    if bad:
        raise PlanError(f"--formats: unknown {', '.join(bad)}; python-can writes {', '.join(LOG_FORMATS)}")
    rig = rig_topology(args.rig)
    scene = on_rig(scene, rig)  # a sheet rig: the scene takes its shape, and is analysed as a sheet
    topology = None if rig == AS_BUILT else rig.as_dict()
    return scene, make_plan(scene, t_end_s=args.t_end, pwm_limit=args.pwm_limit, rig_cells=rig.n, topology=topology)


def _options(args):
    from .runner import Options

    return Options(
        repeats=args.repeats,
        settle_s=args.settle,
        early_stop=not args.no_early_stop,
        relax_s=args.relax,
        rest_timeout_s=args.rest_timeout,
        keep_going=args.keep_going,
        silence_s=args.silence,
        cmd_timeout_s=args.timeout,
        formats=tuple(f.strip().lstrip(".") for f in args.formats.split(",") if f.strip()),
    )


def execute(
    scene: Scene,
    plan: ExperimentPlan,
    channel: str,
    interface: str,
    out: Path,
    opts: Options,
    *,
    open_wait=None,
    plots=True,
    hook=None,
    report=None,
    plain_slcan=False,
    live=None,
    source: str = "rig",
) -> tuple[int, dict]:
    """Open the bus, run, always switch the drive off, write summary.json and plots. Returns (exit code, summary).

    source: "rig", or "rehearsal:hil" against the emulator's pty: the label of the log files, the summary, the
    NPZ files and the plots (a rehearsal is never written as a rig measurement)."""
    from . import summary as S
    from .fastslcan import open_bus
    from .runner import CommandFailed, Experiment, LinkError

    report = report or (lambda text: print(text, file=sys.stderr, flush=True))
    t_start = time.time()
    try:
        bus = open_bus(interface, channel, open_wait, plain_slcan)
    except KeyboardInterrupt:
        report("interrupted while opening the port (nothing was sent)")
        return EXIT_INTERRUPTED, {}
    except Exception as e:
        report(f"error: cannot open {interface} channel {channel}: {e}")
        return EXIT_ABORTED, {}
    port = getattr(bus, "serialPortOrig", None)  # slcan: a device that stops reading must not block a write forever
    if port is not None and getattr(port, "write_timeout", 0) is None:
        port.write_timeout = 2.0
    rc, error = EXIT_OK, None
    exp = None
    try:
        exp = Experiment(bus, plan, out, opts, report=report, hook=hook, live=live, source=source)
        exp.run()
    except KeyboardInterrupt:
        rc, error = EXIT_INTERRUPTED, "interrupted (Ctrl-C)"
    except (LinkError, CommandFailed) as e:
        rc, error = EXIT_ABORTED, str(e)
    except Exception as e:  # any bug or library error: still switch the drive off below, then say what it was
        rc, error = EXIT_ABORTED, f"{type(e).__name__}: {e}"
    finally:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN) if _main_thread() else None
        try:
            if exp is not None:
                exp.finish()
        finally:
            try:
                bus.shutdown()
            except Exception:
                pass
            if old is not None:
                signal.signal(signal.SIGINT, old)
    if error:
        report(f"error: run aborted: {error}")
    if exp is None:
        return rc, {}
    wall = time.time() - t_start
    summary, plot_src = S.build(exp, scene, wall, error, source=source)
    files = []
    if plot_src is not None:
        sc, res = plot_src
        from host_emulator.workbench.datasets import from_run, to_npz

        ds = from_run(sc, res.t, res.alpha, res.beta, summary, source)
        ds.attrs["repeat"] = int(res.info["repeat"])
        ds.attrs["samples_held_note"] = "a lost sample of a present cell holds its previous value; absent cells are 0"
        to_npz(ds, out / "trajectories.npz")
        files.append("trajectories.npz")
        if plots:
            from host_emulator.workbench.plots import plot_run

            miss = summary["missing_cells"]
            name = f"{sc.name}, repeat {res.info['repeat']}" + (f" [no data: cells {miss}, drawn as 0]" if miss else "")
            files += [f.name for f in plot_run(res, sc, out, source=source, name=name)]
    summary["files"] = (
        ["summary.json"]
        + files
        + [f for f in summary["log_files"] if (out / f).exists()]
        + [
            f"repeat_{r['repeat']:02d}.npz"
            for r in summary["per_repeat"]
            if (out / f"repeat_{r['repeat']:02d}.npz").exists()
        ]
    )
    S.write(out, summary)
    if rc == EXIT_OK and (
        summary["failed_commands"]
        or summary["missing_cells"]
        or summary["samples_lost"]
        or not summary["drive_off_confirmed"]
        or summary.get("cell_identity_mismatch")
    ):
        rc = EXIT_PROBLEMS
    return rc, summary


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def print_summary(s: dict, out: Path) -> None:
    print(
        f"scene {s['scene']} ({s.get('source', 'rig')}): {s['repeats_completed']}/{s['repeats']} repeat(s) completed, "
        f"{s['wall_s']:.1f} s wall" + (f"; ABORTED: {s['aborted']}" if s["aborted"] else "")
    )

    def f(v, unit=""):
        return "none" if v is None else (f"{v:.4g}{unit}" if isinstance(v, float) else f"{v}{unit}")

    print(
        f"  steady: {s['steady']}   pattern period: {f(s['pattern_period_cells'], ' cells')} "
        f"(repeats: {', '.join(f(v) for v in s['pattern_period_cells_repeats'])})   "
        f"oscillation period: {f(s['oscillation_period_s'], ' s')}"
    )
    print(
        f"  at rest: {s['at_rest']}   domain walls: {f(s['domain_walls'])} "
        f"(repeats: {', '.join(f(v) for v in s['domain_walls_repeats'])})"
        + (f" at bonds {', '.join(f'{b:g}' for b in s['domain_wall_bonds'])}" if s.get("domain_wall_bonds") else "")
    )
    print("  final alpha (rad, mean): " + " ".join("  n/a" if v is None else f"{v:+.2f}" for v in s["final_alpha_rad"]))
    if s["repeats"] > 1:
        print(
            "  spread (std, rad):       "
            + " ".join("  n/a" if v is None else f"{v:5.2f}" for v in s["final_alpha_std_rad"])
        )
    print(
        f"  missing cells: {s['missing_cells'] or 'none'}; failed commands: {len(s['failed_commands'])}; "
        f"gaps: {s['gaps']} ({s['samples_lost']} samples lost); drive off confirmed: {s['drive_off_confirmed']}"
    )
    prov = s.get("provenance", {})
    if "cell_fw_version" in prov:
        print(
            f"  cells: firmware {prov['cell_fw_version']}; protocol map {prov['cell_map_id']}; "
            f"no identity: {prov['cell_identity_missing']}"
            + (f"; MAP ID MISMATCH: cells {s['cell_identity_mismatch']}" if s.get("cell_identity_mismatch") else "")
        )
    print(f"  wrote {out}/summary.json, " + ", ".join(s["files"][1:]))


def cmd_run(
    args: argparse.Namespace,
    channel: str | None = None,
    interface: str | None = None,
    open_wait: float | None = None,
    source: str = "rig",
) -> int:
    from .plan import PlanError

    try:
        scene, plan = _prepare(args)
        opts = _options(args)
    except PlanError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    channel = channel or args.channel
    interface = interface or args.interface
    if source == "rig":
        from metacell_tools.rigtools.logger import channel_source

        if channel_source(interface, channel) == "emulator:hil":  # a pty: the emulator's serve, never the rig
            source = "rehearsal:hil"
            print(f"note: {channel} is a pseudo-terminal (the emulator's serve): labelled {source}", file=sys.stderr)
    out = Path(args.out or Path("out") / ("rig" if source == "rig" else "rehearsal") / scene.name)
    from metacell_common.outpaths import check_out_dir, check_out_file, first_problem

    problem = first_problem(
        check_out_dir(out), check_out_file(args.live_png, "--live-png") if getattr(args, "live_png", None) else None
    )
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    live = make_live(args, scene, out, source)
    try:
        rc, summary = execute(
            scene,
            plan,
            channel,
            interface,
            out,
            opts,
            open_wait=open_wait if open_wait is not None else getattr(args, "open_wait", None),
            plots=not args.no_plots,
            plain_slcan=args.plain_slcan,
            live=live,
            source=source,
        )
    except BaseException:
        if live is not None:
            live.tracker.terminate()
        raise
    if summary:
        print_summary(summary, out)
        from .summary import push_lines

        for line in push_lines(summary):
            print(line)
    end_live(live)
    return rc


def cmd_rehearse(args: argparse.Namespace) -> int:
    from .plan import PlanError
    from .rehearse import Serve, ServeError, serve_overrides

    try:
        scene, plan = _prepare(args)
        _options(args)
        if scene.model == "image":  # the rehearsal's server is the hil emulator's: it would not be what was asked
            raise PlanError(
                "model = image: a rehearsal runs the hil emulator's serve; for the flashed images run `python -m "
                "host_emulator serve SCENE --slcan --set model=image` and `experiment run --channel PTY@115200`"
            )
    except PlanError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    from metacell_common.outpaths import check_out_dir

    problem = check_out_dir(Path(args.out or Path("out") / "rehearsal" / scene.name))  # where cmd_run writes
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    extra = []
    for name in ("absent", "stuck", "babble"):
        if getattr(args, name):
            extra += [f"--{name}", getattr(args, name)]
    per = plan.t_end_s + args.relax + args.rest_timeout + 30
    duration = args.serve_duration if args.serve_duration is not None else per * args.repeats + 60
    try:
        with Serve(args.scene, serve_overrides(scene, args.set), extra, duration_s=duration) as srv:
            print(f"rehearsal: emulated primary on {srv.pty}", file=sys.stderr, flush=True)
            return cmd_run(args, channel=srv.channel, interface="slcan", open_wait=0.1, source="rehearsal:hil")
    except ServeError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_ABORTED


def cmd_compare(args: argparse.Namespace) -> int:
    from .compare import CompareError, compare

    try:
        table, png = compare(
            Path(args.a), Path(args.b), Path(args.out) if args.out else None, (args.source_a, args.source_b)
        )
    except CompareError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    print(table)
    print(f"wrote {png}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    from metacell_common.outpaths import created_mark, remove_created_since

    args = parser().parse_args(argv)
    mark = created_mark()
    try:
        rc = {"run": cmd_run, "rehearse": cmd_rehearse, "compare": cmd_compare}[args.cmd](args)
    except Exception as e:  # noqa: BLE001 - the last guard: one line, never a traceback (MC_DEBUG=1 shows it)
        from metacell_common.cli import unexpected

        return unexpected(e, "experiment")
    if rc == EXIT_USAGE:
        remove_created_since(mark)  # a rejection leaves no empty directory behind
    return rc
