"""A catalogue of the runs and captures under a folder (``he.runs(DIR)``, ``python -m host_emulator runs DIR``): one
row per run directory, experiment directory or capture, from what each already carries (summary.json, the NPZ's
attributes), as a pandas DataFrame.

Rows, found recursively (hidden folders skipped): a directory holding a summary.json (an emulator run or an
experiment run/rehearsal; nothing under it is listed again), and a capture file outside such directories (a
logger NPZ in the run layout, a logger CSV without its NPZ, a python-can log). A file that cannot be read is a row
with its reason in ``note``, never an error. Columns (``COLUMNS``):

* path (relative to DIR), kind (run, experiment, capture);
* scene, model, source (emulator:<model>, rehearsal:<model>, rig, unknown);
* parameters: the scene parameters that differ from the defaults (host_emulator.params.Params), ``k=v`` joined;
* pattern: the wavelength 2 (N - 1) / Z in cells (None without walls), walls: Z, wall_bonds: their bonds j + 0.5;
* git: the git revision that wrote it (provenance.git_describe), date: when (provenance.created_utc);
* note: anything the row lacks and why.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["runs", "COLUMNS"]

COLUMNS = (
    "path",
    "kind",
    "scene",
    "model",
    "source",
    "parameters",
    "pattern",
    "walls",
    "wall_bonds",
    "git",
    "date",
    "note",
)
CAPTURE_SUFFIXES = (".npz", ".csv", ".asc", ".blf", ".log", ".trc", ".mf4", ".db", ".nc")
RUN_FILES = ("trajectories.npz",)  # a run directory's own files, never listed as captures


def _changed_params(params: dict) -> str:
    """The parameters of a summary that differ from Params' defaults, ``k=v`` joined (per-cell lists shown whole)."""
    from ..params import Params

    defaults: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(Params)}
    out = []
    for k, v in params.items():
        if k == "cells" or k not in defaults:
            continue
        d = defaults[k]
        if isinstance(v, list):
            out.append(f"{k}=[{', '.join(f'{x:g}' for x in v)}]")
        elif isinstance(d, bool) or isinstance(v, bool):
            if bool(v) != bool(d):
                out.append(f"{k}={str(bool(v)).lower()}")
        elif isinstance(v, (int, float)) and not np.isclose(float(v), float(d), rtol=1e-12, atol=0.0):
            out.append(f"{k}={v:g}")
    return ", ".join(out)


def _walls(profile) -> tuple[float | None, int | None, list[float]]:
    from ..analysis.observables import domain_wall_bonds

    u = np.asarray(profile, dtype=float)
    u = np.where(np.isfinite(u), u, 0.0)
    bonds = domain_wall_bonds(u)
    z = len(bonds)
    return ((2.0 * (u.size - 1) / z) if z else None), z, bonds


def _run_row(d: Path, root: Path) -> dict:
    row: dict[str, Any] = {"path": d.relative_to(root).as_posix() or ".", "kind": "run"}
    try:
        s = json.loads((d / "summary.json").read_text())
    except (OSError, json.JSONDecodeError) as e:
        row["note"] = f"summary.json unreadable: {type(e).__name__}"
        return row
    if not isinstance(s, dict):
        row["note"] = "summary.json is not a table"
        return row
    from .datasets import _summary_source

    prov = s.get("provenance") or {}
    row.update(
        kind="experiment" if "per_repeat" in s or s.get("model") == "rig" else "run",
        scene=s.get("scene"),
        model=s.get("model"),
        source=_summary_source(s),
        parameters=_changed_params(s.get("params") or {}),
        git=prov.get("git_describe"),
        date=prov.get("created_utc"),
    )
    final = s.get("final_alpha_rad")
    if "domain_wall_bonds" in s:
        row.update(
            pattern=s.get("pattern_wavelength_cells"), walls=s.get("domain_walls"), wall_bonds=s["domain_wall_bonds"]
        )
    elif s.get("at_rest"):
        row.update(pattern=None, walls=0, wall_bonds=[])
    elif isinstance(final, list) and final:
        row["pattern"], row["walls"], row["wall_bonds"] = _walls([np.nan if v is None else v for v in final])
        row["note"] = "walls from final_alpha_rad (summary written before domain_wall_bonds)"
    return row


def _capture_row(f: Path, root: Path) -> dict:
    from .datasets import LoadError, final_profile, load

    row: dict[str, Any] = {"path": f.relative_to(root).as_posix(), "kind": "capture"}
    try:
        ds = load(f)
    except (LoadError, OSError, ValueError, KeyError) as e:
        row["note"] = " ".join(str(e).split())[:200]
        return row
    a = ds.attrs
    row.update(
        scene=a.get("scene") or None,
        model=a.get("model") or None,
        source=a.get("source"),
        git=a.get("provenance.git_describe"),
        date=a.get("provenance.created_utc"),
    )
    if ds.sizes.get("time", 0) and "row" not in ds.dims:  # a chain's walls (a sheet has no bonds j + 0.5)
        row["pattern"], row["walls"], row["wall_bonds"] = _walls(final_profile(ds))
    return row


def _walk(root: Path):
    """(kind, path) of every run directory and capture under root, in path order."""
    if (root / "summary.json").is_file():
        yield "run", root
        return
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return
    for p in entries:
        if p.name.startswith("."):
            continue
        if p.is_dir() and not p.is_symlink():
            yield from _walk(p)
        elif p.is_file() and p.suffix.lower() in CAPTURE_SUFFIXES and p.name not in RUN_FILES:
            if p.suffix.lower() == ".csv" and p.with_suffix(".npz").exists():
                continue  # a logger capture's CSV beside its NPZ: one row (the NPZ)
            if p.suffix.lower() == ".csv" and not _capture_csv(p):
                continue
            yield "capture", p


def _capture_csv(p: Path) -> bool:
    """A logger CSV or a python-can CSV (never any CSV: a sweep's or a benchmark's table is no capture)."""
    try:
        with open(p) as f:
            head = f.readline()
    except (OSError, UnicodeDecodeError):
        return False
    return head.startswith("segment,cycle,cell,") or head.startswith("timestamp,arbitration_id")


def runs(folder: str | Path) -> pd.DataFrame:
    """The catalogue of the runs and captures under folder (module docstring): a pandas DataFrame, one row each,
    columns COLUMNS. NotADirectoryError for a folder that is not a directory."""
    import pandas as pd

    root = Path(folder)
    if not root.is_dir():
        raise NotADirectoryError(f"{root}: not a directory")
    rows = [_run_row(p, root) if kind == "run" else _capture_row(p, root) for kind, p in _walk(root)]
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    return df.astype({"walls": "Int64"})


def runs_main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator runs",
        description="A catalogue of the runs and captures under a folder: scene, model, parameters, pattern, walls, "
        "source, git revision and date, one row each (he.runs(DIR) gives the same as a pandas DataFrame).",
        epilog="examples:\n  python -m host_emulator runs out\n  python -m host_emulator runs out --csv out/runs.csv",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("folder", help="the folder to search (recursively)")
    ap.add_argument("--csv", default=None, metavar="FILE", help="also write the catalogue as CSV to FILE")
    args = ap.parse_args(argv)
    folder = Path(args.folder)
    if not folder.is_dir():
        print(f"runs: error: {folder}: not a directory", file=sys.stderr)
        return 2
    if args.csv:
        from ..outpaths import check_out_file

        problem = check_out_file(args.csv, "--csv", (".csv",))
        if problem:
            print(f"runs: error: {problem}", file=sys.stderr)
            return 2
    df = runs(folder)
    if df.empty:
        print(f"no runs or captures under {folder}")
    else:
        import pandas as pd

        with pd.option_context("display.max_rows", None, "display.max_columns", None, "display.width", 250):
            print(df.drop(columns=["note"] if df["note"].isna().all() else []).to_string(index=False))
    if args.csv:
        df.to_csv(args.csv, index=False)
        print(f"wrote {args.csv}")
    return 0
