"""summary.json of a rig run or a rehearsal: the keys of `python -m host_emulator run` (source = "rig" and
model = "rig" on the rig; source = "rehearsal:hil" and model = "hil" against the emulator) plus repeats, spread,
every problem seen and the cells' identity.

Top-level observables over N repeats: final_alpha_rad / final_beta_rad are the per-cell mean
of the repeats' final angles (spread: *_std_rad, *_min_rad, *_max_rad); steady is true only if
every repeat was; pattern_period_cells and oscillation_period_s are the median of the
repeats' values (None if no repeat had one). Cells without a single sample are null.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from host_emulator.analysis.observables import domain_wall_bonds, observables, spatial_period
from host_emulator.analysis.summary import summarize
from host_emulator.controller import RunResult
from host_emulator.scene import Scene
from metacell_common.cli import cells_text
from metacell_common.provenance import provenance

from .runner import Experiment, Repeat, Series, series


def json_ready(v: Any) -> Any:
    """numpy -> Python, non-finite floats -> None (a summary never holds NaN)."""
    if isinstance(v, dict):
        return {str(k): json_ready(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_ready(x) for x in v]
    if isinstance(v, np.ndarray):
        return json_ready(v.tolist())
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    return v


def _longest_run(mask) -> slice:
    best, start = slice(0, 0), None
    for i, m in enumerate(list(mask) + [False]):
        if m and start is None:
            start = i
        if not m and start is not None:
            if i - start > best.stop - best.start:
                best = slice(start, i)
            start = None
    return best


MOVE_COUNTS = 2  # a pushed cell has moved once its angle left the one at the send by this many counts
LATE_CYCLES = 4  # a push acknowledged later than this many poll cycles after its recorded send left late


def poll_cycle(arr: dict) -> float | None:
    """The primary's poll cycle (s): the median interval between a cell's consecutive samples."""
    d = np.diff(arr["t_s"], axis=0)
    d = d[np.isfinite(d) & (d > 0)]
    return float(np.median(d)) if d.size else None


def push_timing(perturbations: list, arr: dict, t0: float | None, cycle: float | None) -> list:
    """The perturbation records with when the plant first showed each push and the delays between the three times.

    sent_s: the primary's clock of the newest sample the laptop had read when the command left (the runner's view);
    acked_s: that of the newest sample before the cell's CMD_RESULT on the port (the primary sends its frames in
    order, so this dates the acknowledgement on the primary's clock however late the laptop reads it); moved_s: the
    first sample of the pushed cell's chain (its own time) at least MOVE_COUNTS counts from its last sample at or
    before the send (None: it never moved). late: acknowledged more than LATE_CYCLES poll cycles after the send,
    i.e. the laptop was reading the primary's frames late and the push left later than sent_s says."""
    out = []
    for p in perturbations:
        q = dict(p)
        j = int(q["cell"]) - 1
        moved = None
        if t0 is not None and j < arr["t_s"].shape[1] and q.get("sent_s") is not None:
            t = arr["t_s"][:, j] - t0
            c = arr[f"{q.get('chain', 'alpha')}_counts"][:, j]
            ok = np.isfinite(t) & np.isfinite(c)
            t, c = t[ok], c[ok]
            before = np.nonzero(t <= q["sent_s"])[0]
            if before.size:
                after = np.nonzero((t > q["sent_s"]) & (np.abs(c - c[before[-1]]) >= MOVE_COUNTS))[0]
                moved = float(t[after[0]]) if after.size else None
        ack = q.get("acked_s")
        q["moved_s"] = moved
        q["ack_after_send_s"] = None if ack is None else ack - q["sent_s"]
        q["move_after_ack_s"] = None if ack is None or moved is None else moved - ack
        q["late"] = bool(ack is not None and cycle is not None and ack - q["sent_s"] > LATE_CYCLES * cycle)
        out.append(q)
    return out


def push_lines(summary: dict) -> list[str]:
    """One line per push of every repeat: planned, sent, acknowledged and moved times; late ones said so."""
    lines = []

    def f(v):
        return "-" if v is None else f"{v:.3f}"

    for r in summary.get("per_repeat", []):
        for p in r.get("perturbations", []):
            late = (
                f"  LATE: acknowledged {p['ack_after_send_s']:.3f} s after the recorded send (the laptop read the "
                "primary's frames late)"
                if p.get("late")
                else ""
            )
            lines.append(
                f"  push {p['label']} (repeat {r['repeat']}): planned {f(p.get('planned_s'))} s, sent "
                f"{f(p.get('sent_s'))} s, acknowledged {f(p.get('acked_s'))} s, moved {f(p.get('moved_s'))} s "
                f"(poll cycle {f(r.get('poll_cycle_s'))} s){late}"
            )
    return lines


def repeat_result(rep: Repeat, n_cells: int) -> tuple[dict, Series | None]:
    """(per-repeat record, Series or None) of one repeat."""
    arr = rep.decoder.arrays()
    cycle = poll_cycle(arr)
    rec = {
        "repeat": rep.index,
        "stopped": rep.stopped,
        "perturbations": push_timing(rep.perturbations, arr, rep.t0, cycle),
        "poll_cycle_s": cycle,
        "rest_before_zero_counts": rep.rest_counts,
        "enabled_cells": rep.enabled_cells,
        "t_enable_s": rep.t0,  # the primary's clock at the drive enable: time 0 of the repeat's series
    }
    per_cell = np.sum(~np.isnan(arr["alpha_counts"]), axis=0) if arr["alpha_counts"].size else np.zeros(n_cells, int)
    gaps = arr["gaps"]
    rec["samples_per_cell"] = per_cell[:n_cells]
    # no frame at all from a cell during the whole repeat (setup included): the cell is missing
    rec["missing_cells"] = [j + 1 for j in range(n_cells) if j >= len(per_cell) or per_cell[j] == 0]
    rec["gaps"] = [{"cell": int(g[1]), "after_cycle": int(g[2] - 1), "lost": int(g[3])} for g in gaps]
    rec["samples_lost"] = int(gaps[:, 3].sum()) if len(gaps) else 0
    # the run is [enable acknowledged, stop decided]; frames after it (drive switching off) are logged, not analysed
    s = series(arr, rep.t0, 0.0, rep.t_stop - rep.t0) if rep.t0 is not None and rep.t_stop is not None else None
    if s is None or s.t.size < 2:
        rec.update(
            t_end_s=0.0,
            steady=False,
            at_rest=False,
            domain_walls=None,
            domain_wall_bonds=None,
            pattern_period_cells=None,
            oscillation_period_s=None,
            final_alpha_rad=[None] * n_cells,
            final_beta_rad=[None] * n_cells,
        )
        return rec, None
    s = dataclasses.replace(
        s, alpha=s.alpha[:, :n_cells], beta=s.beta[:, :n_cells], present=s.present[:n_cells], held=s.held[:n_cells]
    )
    pres = s.present
    obs = observables(s.t, s.alpha[:, pres], s.beta[:, pres]) if pres.any() else {}
    run = _longest_run(pres)
    rec.update(
        t_end_s=float(s.t[-1]),
        steady=obs.get("steady", False),
        # the emulator's observables: a chain at rest has no pattern, whatever a flatness test reads into it
        at_rest=obs.get("at_rest", False),
        domain_walls=obs.get("domain_walls"),
        domain_wall_bonds=_wall_bonds(s.alpha[-1], pres, obs),
        oscillation_period_s=obs.get("oscillation_period_s"),
        pattern_period_cells=(
            spatial_period(s.alpha[-1, run]) if run.stop - run.start >= 3 and not obs.get("at_rest", False) else None
        ),
        final_alpha_rad=[float(v) if p else None for v, p in zip(s.alpha[-1], pres)],
        final_beta_rad=[float(v) if p else None for v, p in zip(s.beta[-1], pres)],
        cells_without_data=[j + 1 for j in range(n_cells) if not pres[j]],
        samples_held=s.held,
    )
    if not pres.all():
        rec["pattern_period_note"] = f"from the longest run of cells with data: {run.start + 1}..{run.stop}"
    return rec, s


def build(
    exp: Experiment, scene: Scene, wall_s: float, error: str | None, source: str = "rig"
) -> tuple[dict, tuple[Scene, RunResult] | None]:
    """(summary dict, (scene, RunResult) of the first repeat with data, for the plots, or None).

    source: "rig" (model "rig") or "rehearsal:<model>" (model: the emulated one). The linear theory is the hil
    model's (the lattice, its motors and their back-EMF), whatever model the scene names: the rig has motors."""
    scene = dataclasses.replace(scene, model="hil")
    n = len(exp.plan.cells)
    recs, first = [], None
    for rep in exp.repeats:
        rec, s = repeat_result(rep, n)
        recs.append(rec)
        if s is not None and first is None:
            first = (rep, s)
    if first is not None:
        rep, s = first
        res = RunResult(s.t, s.alpha, s.beta, wall_s, {"source": source, "repeat": rep.index})
        base = summarize(scene, res, source=source)
    else:
        res = None
        base = {
            "scene": scene.name,
            "t_end_s": 0.0,
            "wall_s": wall_s,
            "realtime_factor": 0.0,
            "steady": False,
            "pattern_period_cells": None,
            "oscillation_period_s": None,
            "amplitude_rad": None,
            "final_alpha_rad": [None] * n,
            "final_beta_rad": [None] * n,
            "growth_rate_per_s": None,
            "dispersion": None,
            "params": dataclasses.asdict(scene.params),
            "perturbation": [p.as_dict() for p in scene.perturbations],
        }
    done = [r for r in recs if r["t_end_s"] > 0]
    fa = np.array([[np.nan if v is None else v for v in r["final_alpha_rad"]] for r in done]).reshape(-1, n)
    fb = np.array([[np.nan if v is None else v for v in r["final_beta_rad"]] for r in done]).reshape(-1, n)
    with np.errstate(all="ignore"), _quiet():
        stats: dict[str, Any] = {}  # per-cell arrays, or None per cell without any repeat
        for key, x in (("alpha", fa), ("beta", fb)):
            stats[f"final_{key}_rad"] = np.nanmean(x, axis=0) if len(x) else [None] * n
            stats[f"final_{key}_std_rad"] = np.nanstd(x, axis=0) if len(x) else [None] * n
            stats[f"final_{key}_min_rad"] = np.nanmin(x, axis=0) if len(x) else [None] * n
            stats[f"final_{key}_max_rad"] = np.nanmax(x, axis=0) if len(x) else [None] * n

    def median(key):
        v = [r[key] for r in done if r[key] is not None]
        return float(np.median(v)) if v else None

    missing = sorted({j for r in recs for j in r.get("missing_cells", [])})
    total_t = sum(r["t_end_s"] for r in done)
    out = dict(base)
    out.update(
        {
            "model": "rig" if source == "rig" else source.split(":", 1)[-1],
            "source": source,
            "t_end_s": max((r["t_end_s"] for r in done), default=0.0),
            "wall_s": wall_s,
            "realtime_factor": total_t / wall_s if wall_s > 0 else 0.0,
            "steady": bool(done) and all(r["steady"] for r in done),
            "at_rest": bool(done) and all(r["at_rest"] for r in done),
            "domain_walls": median("domain_walls"),
            "domain_walls_repeats": [r["domain_walls"] for r in done],
            "domain_wall_bonds": _most_common([r.get("domain_wall_bonds") for r in done]),
            "domain_wall_bonds_repeats": [r.get("domain_wall_bonds") for r in done],
            "pattern_period_cells": median("pattern_period_cells"),
            "oscillation_period_s": median("oscillation_period_s"),
            **stats,
            "amplitude_rad": float(np.nanmax(np.abs(stats["final_alpha_rad"])))
            if len(fa) and np.isfinite(np.asarray(stats["final_alpha_rad"], float)).any()
            else None,
            "repeats": len(exp.repeats),
            "repeats_completed": len([r for r in recs if r["stopped"] in ("steady", "t_end")]),
            "per_repeat": recs,
            "pattern_period_cells_repeats": [r["pattern_period_cells"] for r in done],
            "missing_cells": missing,
            "failed_commands": exp.failures,
            "late_pushes": sum(1 for r in recs for p in r["perturbations"] if p["late"]),
            "gaps": sum(len(r["gaps"]) for r in recs),
            "samples_lost": sum(r["samples_lost"] for r in recs),
            "drive_off_confirmed": exp.safe == [],
            "drive_off_unconfirmed_cells": exp.safe if exp.safe is not None else "link lost: none confirmed",
            "aborted": error,
            "plan": exp.plan.as_dict(),
            "commands": exp.commands,
            "frames": exp.frames,
            "corrupt_lines": exp.corrupt,
            "log_files": [p.name for p in exp.log_files],
        }
    )
    out.pop("solver", None)
    out["provenance"] = provenance() | identity_provenance(exp.identity)  # code, libraries, time, command, cells
    out["cell_identity"] = {str(j): r for j, r in sorted(exp.identity.items())}
    out["cell_identity_mismatch"] = sorted(j for j, r in exp.identity.items() if r.get("map_id_matches") is False)
    return json_ready(out), (None if res is None else (scene, res))


def identity_provenance(identity: dict) -> dict:
    """Flat strings for the provenance block: each distinct firmware version, build and protocol map id with the
    cells that reported it (e.g. "1.0 (cells 1-16)"), and the cells that sent no identity."""
    out = {}
    for key, name in (("fw_version", "cell_fw_version"), ("build", "cell_build"), ("map_id", "cell_map_id")):
        groups: dict = {}
        for j, r in identity.items():
            if key in r:
                groups.setdefault(r[key], []).append(j)
        out[name] = "; ".join(f"{v} (cells {cells_text(js)})" for v, js in sorted(groups.items())) or "none read"
    silent = sorted(j for j, r in identity.items() if "error" in r)
    out["cell_identity_missing"] = cells_text(silent) if silent else "none"
    return out


class _quiet:
    """Silence numpy's all-NaN warnings (missing cells are reported, not warned about)."""

    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *a):
        return self._w.__exit__(*a)


def write(out: Path, summary: dict) -> Path:
    f = Path(out) / "summary.json"
    f.write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return f


def _wall_bonds(final_alpha: np.ndarray, present: np.ndarray, obs: dict) -> list[float] | None:
    """Where the walls of a repeat's final alpha are: the bonds j + 0.5 between cells j and j + 1 (cells numbered
    on the rig: a cell without data is left out, as the emulator's domain_wall_bonds skips it); [] at rest; None
    without any data."""
    if not present.any():
        return None
    if obs.get("at_rest", False):
        return []
    missing = [j + 1 for j in range(len(present)) if not present[j]]
    return domain_wall_bonds(np.where(present, final_alpha, 0.0), skip=missing)


def _most_common(lists: list) -> list[float] | None:
    """The wall positions most repeats agree on (the first such in repeat order); None without a repeat."""
    known = Counter(tuple(v) for v in lists if v is not None)  # equal counts: in the order first met
    if not known:
        return None
    return list(known.most_common(1)[0][0])
