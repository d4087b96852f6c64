"""One dataset layout for every run, rig or emulated: an xarray.Dataset over (time, cell), and the NPZ file of it.

``load(path)`` opens any of:

* an emulator run directory (``python -m host_emulator run --out DIR``: summary.json + trajectories.npz);
* an experiment directory (``python -m metacell_tools.experiment run|rehearse --out DIR``): the drive-on part of
  the first repeat with data, or ``repeat=k`` (from repeat_kk.npz, the logger arrays of that repeat);
* a logger capture (``python -m metacell_tools.rigtools.logger -o PREFIX``: PREFIX.npz or PREFIX.csv);
* a python-can log (``python -m can.logger -f run.asc``; ASC, BLF, LOG, TRC, MF4, SQLite, python-can's CSV),
  decoded with the project's DBC (protocol/metacell.dbc through cantools) by the capture decoder
  (protocol.capture.SampleDecoder, the logger's);
* an NPZ in this layout, or the older layouts (the emulator's ``t, alpha, beta``; the logger's ``t_s, alpha_rad,
  ...``), and a NetCDF file written from such a dataset.

The dataset (format ``metacell-run/1``):

* dims ``time`` (s; emulator: from the run's start; rig and rehearsal runs: from the drive enable; captures: from
  the first sample) and ``cell`` (1..N); a sheet's (attributes ``topology.cells = [rows, cols]``,
  ``topology.lattice``, ``topology.boundary``: Topology.as_dict(), recorded for any lattice but the open chain)
  ``time``, ``row`` and ``col`` (1-based), with ``cell`` the 2-D coordinate of the cell numbers
  ((row - 1) * cols + col); the NPZ keeps every variable as (time, cell) in cell order either way;
* ``alpha``, ``beta`` (rad, CCW positive; NaN where a cell sent no sample);
* where known: ``torque_alpha``, ``torque_beta`` (N m, the reaction torque the controller commands: the
  lattice and continuum models' law at the sampled state; the hil model's firmware torque is not recorded),
  ``flags`` (the cell's CELL_SAMPLE flags, -1 = no sample), ``sample_time`` (s, the primary's clock when that
  cell was sampled), ``alpha_counts``/``beta_counts`` (encoder counts), ``host_time`` (s, Unix time of
  reception). Velocities are in neither the emulator's sampled output nor the rig's frames: not estimated here;
* attributes: ``source`` (``emulator:<model>``, ``rehearsal:<model>``, ``rig``, or ``unknown`` when nothing in
  the file says which: a python-can log cannot tell an emulated primary from a real one, pass ``source=``),
  ``format``, ``origin`` (the path read), ``scene`` and every scene parameter when known, units, provenance.

The NPZ file (``to_npz``) holds the same: ``format``, ``time``, ``cell``, ``alpha``, ``beta``, the optional
variables above, the rig's ``cycle``, ``segment``, ``partial`` (per row: logging started or stopped inside that
cycle, so some cells have no sample in it; docs/datapath.md, "Partial cycles") and ``gaps`` (segment, cell, first
missing cycle, count), and ``attrs`` (the attributes as one JSON string). It is written to a temporary name and
renamed (``save_npz_atomic``): a reader never finds a cut or empty NPZ, even after a full disk or a kill.
"""

from __future__ import annotations

import json
import struct
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from metacell_common.runlayout import (
    EXTRA_ARRAYS,
    FORMAT,
    VARIABLES,
    _json_attrs,
    logger_layout,
    save_npz_atomic,
    write_npz,
)
from protocol.capture import SampleDecoder, gaps_from_rows, read_rows, rows_to_arrays
from protocol.wire import N_CELLS, frame_kind

from ..physics import reaction
from ..topology import Topology, TopologyError
from .api import _flat, netcdf_attrs, observable_attrs

if TYPE_CHECKING:
    import xarray as xr

    from ..scene import Scene

__all__ = [
    "FORMAT",
    "VARIABLES",
    "load",
    "make_dataset",
    "to_npz",
    "read_npz",
    "from_run",
    "from_logger_arrays",
    # the run layout's NPZ writer (metacell_common.runlayout), here under its old names
    "EXTRA_ARRAYS",
    "logger_layout",
    "save_npz_atomic",
    "write_npz",
    "_json_attrs",
]

CAN_LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc", ".mf4", ".db")
FOREIGN_MAX = 0.05  # a python-can log with more of its frames outside the project's CAN database is refused
TIME_SLACK_S = 1e-3  # a cycle may start this much before the previous one ended (each cell's own clock reading)


class LoadError(ValueError):
    """A path that is not a run, a capture or a log this module reads (one line: what and why)."""


# ---- building ----------------------------------------------------------------------------------------------
def make_dataset(
    time: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    *,
    attrs: Mapping[str, Any] | None = None,
    cell: np.ndarray | None = None,
    **extra: np.ndarray,
) -> xr.Dataset:
    """The layout above from arrays: time (T,), alpha/beta (T, N); extra (T, N) variables by their VARIABLES name,
    or (T,) cycle / segment rows, or the (G, 4) gap table. Attributes naming a sheet (topology.*) make the
    variables (time, row, col)."""
    import xarray as xr

    a = np.asarray(alpha, dtype=float)
    n = a.shape[1]
    cells = np.arange(1, n + 1) if cell is None else np.asarray(cell, dtype=int)
    topo = topology_of_attrs(attrs or {})
    sheet = topo is not None and topo.is_sheet
    if topo is not None and (topo.n != n or not np.array_equal(cells, np.arange(1, n + 1))):
        raise ValueError(f"make_dataset: attributes name a {topo.describe()}, the data hold {n} cells")
    space: tuple[str, ...] = ("row", "col") if sheet else ("cell",)

    def shaped(arr: np.ndarray) -> np.ndarray:
        return topo.grid(arr) if sheet and topo is not None else arr

    data: dict[str, Any] = {}
    for name, arr in (("alpha", a), ("beta", np.asarray(beta, dtype=float)), *extra.items()):
        if arr is None:
            continue
        arr = np.asarray(arr)
        if name in VARIABLES:
            units, long = VARIABLES[name]
            data[name] = (("time", *space), shaped(arr), {"units": units, "long_name": long})
        elif name in ("cycle", "segment"):
            data[name] = (("time",), arr.astype(np.int64), {"long_name": f"poll {name} of the row"})
        elif name == "partial":
            data[name] = (
                ("time",),
                arr.astype(bool),
                {"long_name": "logging started or stopped inside this cycle (some cells have no sample in it)"},
            )
        elif name == "gaps":
            data[name] = (
                ("gap", "gap_field"),
                arr.astype(np.int64).reshape(-1, 4),
                {"long_name": "lost samples: segment, cell, first missing cycle, count"},
            )
        else:
            raise ValueError(
                f"make_dataset: unknown variable {name!r}; known: {', '.join([*VARIABLES, *EXTRA_ARRAYS])}"
            )
    coords: dict[str, Any] = {"time": ("time", np.asarray(time, dtype=float), {"units": "s", "long_name": "time"})}
    if sheet and topo is not None:
        coords["row"] = ("row", np.arange(1, topo.rows + 1), {"long_name": "row of the sheet (1-based)"})
        coords["col"] = ("col", np.arange(1, topo.cols + 1), {"long_name": "column of the sheet (1-based)"})
        coords["cell"] = (("row", "col"), topo.grid(cells), {"long_name": "cell index j = (row - 1) * cols + col"})
    else:
        coords["cell"] = ("cell", cells, {"long_name": "cell index j"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update({"format": FORMAT, "source": "unknown", **(dict(attrs) if attrs else {})})
    if "gap_field" in ds.dims:
        ds = ds.assign_coords(gap_field=["segment", "cell", "first_missing_cycle", "count"])
    return ds


def run_arrays(scene: Scene, time, alpha, beta, source: str) -> dict[str, np.ndarray]:
    """A run's arrays in this layout (numpy only): time, cell, alpha, beta and, for an emulated lattice or
    continuum model, the commanded reaction torques at every sample (the law of physics.py, clipped to the
    actuator limit on the lattice as its plant does)."""
    a, b = np.asarray(alpha, float), np.asarray(beta, float)
    out: dict[str, np.ndarray] = {
        "time": np.asarray(time, float),
        "cell": np.arange(1, a.shape[1] + 1),
        "alpha": a,
        "beta": b,
    }
    if source.startswith("emulator:") and scene.model in ("lattice", "continuum"):
        ra, rb = reaction(scene.params, a, b)
        if scene.model == "lattice":
            lim = scene.params.torque_limit_nm
            ra, rb = np.clip(ra, -lim, lim), np.clip(rb, -lim, lim)
        out["torque_alpha"], out["torque_beta"] = ra, rb
    return out


def run_attrs(scene: Scene, summary: dict | None, source: str) -> dict:
    """Attributes of a run: the scene (every parameter), the scalar observables and theory, provenance, source."""
    return {**netcdf_attrs(scene, summary), "source": source}


def from_run(scene: Scene, time, alpha, beta, summary: dict | None = None, source: str | None = None) -> xr.Dataset:
    """An emulator run (or a rig series with its scene) in the layout (run_arrays, run_attrs)."""
    src = source or (summary or {}).get("source") or f"emulator:{scene.model}"
    arr = run_arrays(scene, time, alpha, beta, src)
    return make_dataset(arr.pop("time"), arr.pop("alpha"), arr.pop("beta"), attrs=run_attrs(scene, summary, src), **arr)


def write_run(path: str | Path, scene: Scene, time, alpha, beta, summary: dict | None, source: str) -> Path:
    """A run's NPZ in this layout without building a dataset (the run command writes trajectories.npz with it)."""
    return write_npz(path, run_arrays(scene, time, alpha, beta, source), run_attrs(scene, summary, source))


def from_logger_arrays(arr: Mapping[str, np.ndarray], attrs: Mapping[str, Any] | None = None, t0: float | None = None):
    """The logger's arrays as a dataset (logger_layout); attribute t_origin_s: the primary-clock time of time 0."""
    lay = logger_layout(arr, t0)
    t_origin = lay.pop("t_origin_s")
    return make_dataset(
        lay.pop("time"),
        lay.pop("alpha"),
        lay.pop("beta"),
        cell=lay.pop("cell"),
        attrs={"t_origin_s": t_origin, **(dict(attrs) if attrs else {})},
        **lay,
    )


def topology_of_attrs(attrs: Mapping[str, Any]) -> Topology | None:
    """The Topology a dataset's topology.* attributes record, None without them (an open chain, a capture); a
    ValueError naming the attribute when they do not make one."""
    if "topology.lattice" not in attrs:
        return None
    cells = np.ravel(np.asarray(attrs.get("topology.cells")))
    try:
        if cells.size == 0 or not np.all(np.isfinite(cells.astype(float))) or np.any(cells != np.round(cells)):
            raise TopologyError(f"topology.cells = {attrs.get('topology.cells')!r}: expected n or [rows, cols]")
        spec = int(cells[0]) if cells.size == 1 else [int(c) for c in cells]
        return Topology.from_spec(spec, str(attrs["topology.lattice"]), str(attrs.get("topology.boundary", "open")))
    except (TopologyError, TypeError, ValueError) as e:
        raise ValueError(f"attribute {e}") from None


def cell_values(ds: xr.Dataset, var: str) -> np.ndarray:
    """A variable of the layout as (time, cell) in cell order: a sheet's (time, row, col) flattened row by row."""
    v = ds[var]
    if "row" in v.dims:
        return v.transpose("time", "row", "col").values.reshape(v.sizes["time"], -1)
    return v.values


# ---- the NPZ file -------------------------------------------------------------------------------------------
def to_npz(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a dataset of this layout as NPZ (compressed; a sheet's variables as (time, cell) in cell order);
    returns the path."""
    arrays = {
        k: cell_values(ds, k) if k in VARIABLES else ds[k].values
        for k in ("time", *VARIABLES, *EXTRA_ARRAYS)
        if k in ds.variables
    }
    arrays["cell"] = np.ravel(ds["cell"].values)
    return write_npz(path, arrays, {k: v for k, v in ds.attrs.items() if k != "origin"})


def read_npz(path: str | Path, attrs: Mapping[str, Any] | None = None) -> xr.Dataset:
    """An NPZ of this layout, of the emulator's older ``t, alpha, beta`` or of the logger's older arrays. A file
    that is no NPZ (empty, cut, another format) is a LoadError naming it, never a numpy or zipfile traceback."""
    path = Path(path)
    try:
        return _read_npz(path, attrs)
    except LoadError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as e:
        what = " ".join(str(e).split())[:200] or type(e).__name__
        raise LoadError(f"{path}: not a readable NPZ ({type(e).__name__}: {what})") from None


def _read_npz(path: Path, attrs: Mapping[str, Any] | None) -> xr.Dataset:
    with np.load(path, allow_pickle=False) as z:
        keys = set(z.files)
        if "format" in keys:
            if str(z["format"]) != FORMAT:
                raise LoadError(f"{path}: format {str(z['format'])!r}, this version reads {FORMAT!r}")
            extra = {k: z[k] for k in (*VARIABLES, *EXTRA_ARRAYS) if k in keys and k not in ("alpha", "beta")}
            a = json.loads(str(z["attrs"])) if "attrs" in keys else {}
            return make_dataset(
                z["time"], z["alpha"], z["beta"], cell=z["cell"], attrs={**a, **(attrs or {})}, **extra
            ).assign_attrs(origin=str(path))
        if {"t", "alpha", "beta"} <= keys:  # the emulator's trajectories.npz before this layout
            return make_dataset(z["t"], z["alpha"], z["beta"], attrs=dict(attrs or {})).assign_attrs(origin=str(path))
        if {"t_s", "alpha_counts", "beta_counts", "flags"} <= keys:  # the logger's NPZ before this layout
            arr = {k: z[k] for k in z.files}
            return from_logger_arrays(arr, attrs).assign_attrs(origin=str(path))
    raise LoadError(f"{path}: not a run NPZ (no time/alpha/beta, t/alpha/beta or t_s/alpha_counts arrays)")


# ---- captures -----------------------------------------------------------------------------------------------
def _from_rows(rows: np.ndarray, gaps, attrs, path: Path) -> xr.Dataset:
    if gaps is None:  # a CSV alone: the gaps its cycle counters show
        gaps = gaps_from_rows(rows)

    arr = rows_to_arrays(rows, N_CELLS, gaps)  # read_rows refused cells outside the rig's 1..N_CELLS
    _check_time_order(path, arr)
    return from_logger_arrays(arr, attrs)


def read_can_log(path: str | Path, source: str | None = None) -> xr.Dataset:
    """A python-can log file (any format can.LogReader reads), its CELL_SAMPLE frames decoded with the project's DBC
    by the capture decoder (protocol.capture.SampleDecoder: time unwrapped on the primary's heartbeat, gaps found
    on the sequence counters)."""
    import can

    notes: list[str] = []
    dec = SampleDecoder(report=notes.append)
    frames = foreign = 0
    try:
        with can.LogReader(str(path)) as reader:
            for msg in reader:
                if msg.is_error_frame:
                    continue
                if msg.is_extended_id or msg.is_remote_frame or frame_kind(msg.arbitration_id)[0] == "UNKNOWN":
                    foreign += 1
                dec.feed(msg)
                frames += 1
    except Exception as e:  # noqa: BLE001 - python-can's readers parse any bytes: struct.error, zlib.error, ...
        raise LoadError(f"{path}: cannot read as a python-can log ({_why(e)})") from None
    foreign += sum(text.startswith("undecodable") for text in notes)
    if frames and foreign > FOREIGN_MAX * frames:
        raise LoadError(
            f"{path}: {foreign} of {frames} frames ({100 * foreign / frames:.0f} %) are not this protocol's (CAN IDs "
            f"or lengths the project's CAN database does not define; limit {100 * FOREIGN_MAX:g} %): not a capture "
            "of this rig"
        )
    if not dec.rows and not dec.held:
        raise LoadError(f"{path}: {frames} frame(s), none a CELL_SAMPLE of this protocol")
    arr = dec.arrays()
    _check_time_order(path, arr)
    return from_logger_arrays(
        arr,
        {
            "source": source or "unknown",
            "source_note": "" if source else "a python-can log does not say whether a rig or an emulator sent it",
            "capture": "python-can log",
            "frames": frames,
            "decoder_notes": "; ".join(notes[:20]),
        },
    ).assign_attrs(origin=str(path))


def _check_time_order(path: str | Path, arr: Mapping[str, np.ndarray]) -> None:
    """A capture's cycles run forward in time within a segment (the decoder unwraps every sample's clock forward):
    a row whose time lies before an earlier cycle's is data the decoder misread (frames of another protocol that
    happen to use this protocol's IDs), a LoadError."""
    seg, ts = np.asarray(arr["segment"]), np.asarray(arr["t_s"], dtype=float)
    for s in np.unique(seg):
        rows = ts[seg == s]
        t = rows[np.isfinite(rows).any(axis=1)]
        if not len(t):
            continue
        first, last = np.nanmin(t, axis=1), np.nanmax(t, axis=1)
        back = first[1:] < np.maximum.accumulate(last[:-1]) - TIME_SLACK_S
        if back.any():
            i = int(np.argmax(back)) + 1
            raise LoadError(
                f"{path}: times run backwards (segment {int(s)}, row {i}: a cycle at {first[i]:.6g} s follows one "
                f"that ended at {np.maximum.accumulate(last)[i - 1]:.6g} s): not a capture of this rig"
            )


def _logger_csv(path: Path, source: str | None) -> xr.Dataset:
    try:
        rows = read_rows(path)
    except ValueError as e:
        what = " ".join(str(e).split())[:200]
        raise LoadError(f"{path}: not the logger's CSV ({what})") from None
    meta = {}
    npz = path.with_suffix(".npz")
    if npz.exists():  # the capture's attributes (source, provenance) live in its NPZ
        try:
            with np.load(npz, allow_pickle=False) as z:
                if "attrs" in z.files:
                    meta = json.loads(str(z["attrs"]))
        except (OSError, ValueError, EOFError, zipfile.BadZipFile):  # an NPZ a crash left unreadable: the CSV alone
            meta = {}
    if source:
        meta["source"] = source
    meta.setdefault("source", "unknown")
    meta["capture"] = "logger CSV"
    return _from_rows(rows, None, meta, path).assign_attrs(origin=str(path))


def _is_logger_csv(path: Path) -> bool:
    with open(path) as f:
        return f.readline().startswith("segment,cycle,cell,")


# ---- run directories ----------------------------------------------------------------------------------------
def _summary_source(s: dict) -> str:
    """The source a summary.json names; summaries written before the key existed: emulator runs by their model,
    rig-runner summaries (model "rig") told apart by the command line in their provenance."""
    if s.get("source"):
        return str(s["source"])
    if s.get("model") != "rig":
        return f"emulator:{s.get('model', 'unknown')}"
    cmd = str((s.get("provenance") or {}).get("command", ""))
    if " rehearse " in f" {cmd} ":
        return "rehearsal:hil"
    if " run " in f" {cmd} ":
        return "rig"
    return "unknown"


def _scene_attrs(s: dict) -> dict:
    out: dict = {}
    _flat(
        "",
        {
            "scene": s.get("scene", ""),
            "model": s.get("model", ""),
            "params": s.get("params") or {},
            "perturbation": s.get("perturbation") or [],
        },
        out,
    )
    observable_attrs(s, out)
    if s.get("provenance"):
        _flat("provenance", s["provenance"], out)
    return out


def _load_dir(d: Path, source: str | None, repeat: int | None) -> xr.Dataset:
    f = d / "summary.json"
    try:
        s = json.loads(f.read_text())
    except FileNotFoundError:
        s = None
    except json.JSONDecodeError as e:
        raise LoadError(f"{f}: not valid JSON: {e}") from None
    if s is not None and not isinstance(s, dict):
        raise LoadError(f"{f}: not a run summary (a JSON {type(s).__name__}, not an object)")
    if s is None:
        if (d / "trajectories.npz").exists():
            return read_npz(d / "trajectories.npz", {"source": source} if source else None)
        raise LoadError(f"{d}: no summary.json or trajectories.npz (not a run directory)")
    attrs = _scene_attrs(s)
    attrs["source"] = source or _summary_source(s)
    if repeat is not None:
        recs = {int(r["repeat"]): r for r in s.get("per_repeat", [])}
        if repeat not in recs:
            raise LoadError(f"{d}: no repeat {repeat}; repeats: {', '.join(map(str, sorted(recs))) or 'none'}")
        npz = d / f"repeat_{repeat:02d}.npz"
        if not npz.exists():
            raise LoadError(f"{npz}: missing")
        t_enable = recs[repeat].get("t_enable_s")
        ds = read_npz(npz, attrs)
        if t_enable is not None and "t_origin_s" in ds.attrs:  # time from the drive enable, as the summary's series
            shift = float(ds.attrs["t_origin_s"]) - float(t_enable)
            ds = ds.assign_coords(time=ds["time"].values + shift)
            ds["sample_time"] = ds["sample_time"] + shift
            ds.attrs["t_origin_s"] = float(t_enable)
        return ds.assign_attrs(repeat=repeat, origin=str(npz))
    npz = d / "trajectories.npz"
    if not npz.exists():
        raise LoadError(f"{d}: summary.json but no trajectories.npz (a run that produced no data)")
    ds = read_npz(npz, attrs)
    ds.attrs.update(attrs)  # the summary is the authority on what ran
    return ds.assign_attrs(origin=str(d))


def load(path: str | Path, *, source: str | None = None, repeat: int | None = None) -> xr.Dataset:
    """Open a run directory, an experiment directory, a logger capture, a python-can log, an NPZ or a NetCDF file
    (module docstring) as one xarray.Dataset. source: the label for data whose file does not say what produced it
    (``rig``, ``emulator:hil``, ...); repeat: an experiment directory's repeat (default: the summary's first).
    Every input it cannot read is a LoadError of one line naming the path (never a reader's own exception)."""
    try:
        return _load(Path(path), source, repeat)
    except LoadError:
        raise
    except (
        OSError,
        ValueError,
        EOFError,
        LookupError,
        ArithmeticError,
        AttributeError,
        TypeError,
        struct.error,
        zlib.error,
    ) as e:
        raise LoadError(f"{path}: cannot read it ({_why(e)})") from None


def _why(e: BaseException) -> str:
    """'zlib.error: Error -3 while ...' on one line of at most 200 characters of message."""
    name = type(e).__name__
    if name == "error":  # struct.error, zlib.error: the module says what failed
        name = f"{type(e).__module__}.error"
    return f"{name}: {' '.join(str(e).split())[:200] or '(no message)'}"


def _load(p: Path, source: str | None, repeat: int | None) -> xr.Dataset:
    if source is not None and not (source == "rig" or source.split(":")[0] in ("emulator", "rehearsal", "unknown")):
        raise LoadError(f"source={source!r}: expected rig, emulator:<model>, rehearsal:<model> or unknown")
    if p.is_dir():
        return _load_dir(p, source, repeat)
    if not p.exists():
        # a logger prefix (out/run1 for out/run1.npz and .csv)
        for suffix in (".npz", ".csv"):
            if p.with_suffix(suffix).exists() and p.suffix == "":
                return load(p.with_suffix(suffix), source=source)
        raise LoadError(f"{p}: no such file or directory")
    suf = p.suffix.lower()
    if suf == ".npz":
        ds = read_npz(p, {"source": source} if source else None)
        if "source" not in ds.attrs or (ds.attrs["source"] == "unknown" and source):
            ds.attrs["source"] = source or "unknown"
        return ds
    if suf == ".nc":
        import xarray as xr

        try:
            with xr.open_dataset(p, engine="scipy") as nc:
                ds = nc.load()
        except Exception as e:  # noqa: BLE001 - scipy's reader says "not a valid NetCDF 3 file" as a TypeError
            raise LoadError(f"{p}: cannot read as NetCDF ({_why(e)})") from None
        dims = (("time", "cell"), ("time", "row", "col"))
        if not all(k in ds.variables and ds[k].dims in dims for k in ("alpha", "beta")):
            raise LoadError(f"{p}: a NetCDF file but not a run dataset (no alpha, beta over time x cell)")
        if source:
            ds.attrs["source"] = source
        return ds
    if suf == ".csv" and _is_logger_csv(p):
        return _logger_csv(p, source)
    if suf in CAN_LOG_SUFFIXES or suf == ".csv":
        return read_can_log(p, source)
    raise LoadError(
        f"{p}: unknown kind of file (a run directory, .npz, .nc, a logger .csv or a python-can log: "
        f"{', '.join(CAN_LOG_SUFFIXES)}, .csv)"
    )


def final_profile(ds: xr.Dataset, var: str = "alpha") -> np.ndarray:
    """Each cell's last sample (N,) in cell order (a sheet's row by row): the final profile of a run, NaN for a
    cell that never sent one."""
    a = cell_values(ds, var)
    out = np.full(a.shape[1], np.nan)
    for j in range(a.shape[1]):
        ok = np.flatnonzero(np.isfinite(a[:, j]))
        if len(ok):
            out[j] = a[ok[-1], j]
    return out
