"""`python -m host_emulator sweep`: the command line of sweep(...)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ...models import ConfigError
from .driver import sweep
from .errors import SweepError, SweepFailed
from .grid import parse_grid

EPILOG = """examples:
  python -m host_emulator sweep default --grid params.sigma=0.04:0.12:41 \\
      --grid perturbation.1.torque_Nm=0.005,0.01,0.02,0.04 --seeds 5 \\
      --set model_options.noise.band_spread=0.02 --out out/sweep
  python -m host_emulator sweep default --grid params.sigma=0.05,0.07 --set t_end_s=2 --workers 2 --out out/s2
  dask scheduler --port 8786 &  dask worker tcp://127.0.0.1:8786 --nthreads 1 &
  python -m host_emulator sweep default --grid params.sigma=0.04:0.12:9 --scheduler tcp://127.0.0.1:8786 --out out/s3

Re-running the same command resumes: points already in DIR/points.jsonl are skipped.
Exit codes: 0 every point ran, 1 some points failed (recorded in the dataset), 2 bad input (grid, keys, output
directory, a sweep over the size limits: the figure is given), 3 the sweep could not run on (scheduler unreachable,
cluster did not start, interrupted, write error; finished points are kept and a re-run resumes)."""


def sweep_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator sweep",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run a grid of scene overrides x noise seeds on Dask; write one "
        "xarray dataset (sweep.nc), the phase diagram and a regime map.",
    )
    ap.add_argument("scene", help="shipped scene name or .toml path (see `python -m host_emulator scenes`)")
    ap.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY=SPEC",
        required=True,
        help="a swept key: KEY=START:STOP:NUM (NUM values, ends included) or KEY=V1,V2,...; repeatable",
    )
    ap.add_argument(
        "--seeds",
        type=int,
        default=None,
        metavar="S",
        help="add a coordinate seed = 0..S-1 (sets model_options.noise.seed)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a fixed override for every point, as in `run --set` (e.g. t_end_s=2)",
    )
    ap.add_argument("--out", required=True, metavar="DIR", help="output directory (resumable: re-run to continue)")
    ap.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="an existing Dask scheduler (default: start a local cluster)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local cluster: worker processes (default: the machine's cores)",
    )
    ap.add_argument(
        "--accuracy",
        choices=("fast", "balanced", "exact"),
        default=None,
        help="stepper/step/model fidelity preset of every point, as `run --accuracy` (default: the scene's)",
    )
    ap.add_argument("--chunk", type=int, default=None, metavar="K", help="points per Dask task (default: automatic)")
    ap.add_argument("--retry-failed", action="store_true", help="run the points recorded as failed again")
    ap.add_argument(
        "--map",
        nargs=2,
        default=None,
        metavar=("XKEY", "YKEY"),
        help="the regime map's axes (default: the first two swept keys with more than one value)",
    )
    ap.add_argument(
        "--no-plots",
        action="store_true",
        help="skip phase_diagram.png, regime_map.png (and a sheet's pattern_kinds.png)",
    )
    ap.add_argument("--quiet", action="store_true", help="no progress bar (it shows on a terminal only anyway)")
    args = ap.parse_args(argv)
    try:
        if args.workers is not None and args.workers < 1:
            raise SweepError("--workers must be >= 1")
        if args.chunk is not None and args.chunk < 1:
            raise SweepError("--chunk must be >= 1")
        grid = dict(parse_grid(g) for g in args.grid)
        ds = sweep(
            args.scene,
            grid,
            seeds=args.seeds,
            out=args.out,
            fixed=args.set,
            accuracy=args.accuracy,
            scheduler=args.scheduler,
            workers=args.workers,
            chunk=args.chunk,
            progress=not args.quiet,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            map_keys=args.map,
        )
    except (SweepError, ConfigError, KeyError) as e:
        print(f"error: {e.args[0] if isinstance(e, KeyError) and e.args else e}", file=sys.stderr)
        return 2
    except SweepFailed as e:
        kept = Path(args.out, "points.jsonl")
        where = f"; finished points are kept in {kept}" if kept.exists() else ""
        print(f"error: sweep failed: {e}{where}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(
            f"sweep: interrupted; finished points are kept in {args.out}/points.jsonl (the same command resumes)",
            file=sys.stderr,
        )
        return 3
    except OSError as e:
        print(f"error: sweep failed: cannot write {args.out}: {e.strerror or e}", file=sys.stderr)
        return 3
    st = ds["status"].values.astype(str)
    failed = int((st == "failed").sum())
    print(f"sweep: {st.size} points, {int((st == 'ok').sum())} ok, {failed} failed; wrote {args.out}/sweep.nc")
    if failed:
        errs = ds["error"].values.astype(str)[st == "failed"]
        print(f"  first failure: {errs[0]}", file=sys.stderr)
    return 1 if failed else 0
