"""`python -m host_emulator design` and ``he.design(...)``: from a target pattern to reaction-law parameters.

See docs/design.md. A target is a wavelength in cells (``lambda=10``: Z = 2 (n - 1) / lambda domain walls
anywhere, the rig's reading of a pattern) or a layout of domain walls at named bonds (``walls=5.5,10.5``: between
cells 5|6 and 10|11), and optionally cells that must stay at rest (``--rest 9-16``). The pushes are the
experimenter's (``--push 8``, ``--push 6,10``, ``--push 1:+,16:-``: CCW (+) or CW (-) hand pushes on alpha).

The design, in three steps:

1. first guess from linear theory (analysis.chain): over the free parameters (``--vary``; those in ``--per-cell``
   take one value per domain of the target layout), scipy's differential evolution maximises the linear score:
   the chain's fastest mode (hil theory: inertia and the motors' back-EMF damping) must be stationary, grow, have
   the target's walls (or wall count) and fill every domain, with as large a gap as possible to the next mode;
2. search over batched hil ensembles (workbench.batch, firmware in the loop; on Dask with ``--scheduler``):
   differential evolution again, seeded around the first guess, each generation one batched call, maximising
   the fraction of runs that land on the target over ``search_seeds`` noise seeds (the robustness command's
   noise model) and the corners of the push range (a missed run earning 0.3 x its closeness: the share of the
   target's walls it has and of the chain it fills, so the search can climb before anything lands), plus a
   margin: 0.05 x the linear gap (so among equally successful designs the one farthest from a competing mode
   wins). A candidate that lands in every search run is run again on as many fresh noise seeds (4000..), which
   count too; the search stops at the first candidate that lands in all of them (else after ``maxiter``
   generations, keeping the best). A run lands when its final pattern is steady, has exactly the target's walls
   (sign changes among the cells above 0.1 rad, each rounded to the nearest bond), every cell off the walls
   beyond 0.1 rad and every domain reaching 0.3 rad (a filled pattern, not a bump on a chain at rest), the rest
   cells within 0.1 rad, and no reaction torque beyond the drivers' 5.86 V (44 mN m);
3. verification of the written scene.toml as ``run`` loads it: 20 noise seeds (seeds 2000.., as the robustness
   command) and the whole push range (PUSH_TORQUES_NM x PUSH_DURATIONS_S, no noise).

Parameters stay in the firmware's ranges (|k| <= 0.25 N m/rad, 0 <= alpha* <= 2 pi, k1 > max(k2, 0)) and are
rounded to the registers' resolution (1 uN m/rad, 1 urad). A target the search cannot bring to ``require``
(default 0.9) of the noise seeds is reported as unreachable, with the nearest target that is reachable.
Outputs in --out: design.json, scene.toml, design.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.observables import WALL_THRESHOLD_RAD
from ..params import REACTION_KEYS, Params

__all__ = ["Target", "parse_target", "parse_pushes", "design", "design_main", "lands", "DesignError"]

# the documented range of hand pushes (as the robustness command): torque (N m) x duration (s), no noise
PUSH_TORQUES_NM = (0.005, 0.01, 0.02, 0.04)
PUSH_DURATIONS_S = (0.05, 0.1, 0.2)
SEARCH_PUSHES = ((0.01, 0.05), (0.04, 0.2), (0.005, 0.2), (0.04, 0.05))  # the range's corners, in the search
NOMINAL_PUSH = (0.02, 0.1)  # the scene's push: 20 mN m for 0.1 s, 0.1 s after the start
NOISE = {"band_spread": 0.05, "eta_spread": 0.05}  # the robustness command's noise model
VERIFY_SEED0 = 2000  # verification seeds (the robustness command's)
SEARCH_SEED0 = 3000  # search seeds: never the verification's
CHECK_SEED0 = 4000  # a search candidate that lands in every search run is checked on as many fresh seeds (4000..)
REQUIRE = 0.9
MARGIN_WEIGHT = 0.05
CLOSE_WEIGHT = 0.3  # in the search only: a missed run earns this x how close its walls came (closeness)
FULL_BONUS = 0.1  # in the search only: added to a candidate that landed in every search and check run
# search box of each parameter (N m/rad; alpha* rad): inside the firmware's |k| <= 0.25, 0 <= alpha* <= 2 pi
BOUNDS = {
    "k_ab": (0.002, 0.12),
    "sigma": (0.0, 0.25),
    "k1": (0.02, 0.25),
    "k2": (-0.2, 0.05),
    "alpha_star": (0.3, 2.5),
}
LSB_DIGITS = 6  # register resolution: 1 uN m/rad (gains), 1 urad (alpha*): values rounded to 6 decimals
MIN_GROWTH_PER_S = 1.0  # the target mode must grow at least this fast (e^9 over a 10 s run)
DOMAIN_MIN_RAD = 0.3  # every domain of a landed pattern reaches this |alpha| (about half a pattern's 0.6-0.7 rad)
DOMAIN_FILL_MODE = 0.2  # in the linear theory, every cell of a domain off its walls this share of the mode's peak


class DesignError(ValueError):
    """Bad design input (target, push, parameter names); the message names it."""


# ---- target and pushes -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Target:
    """What the pattern must be: `walls` (bond positions j + 0.5) or only their number `z` (a wavelength target),
    and cells that must stay at rest."""

    kind: str  # "lambda" | "walls"
    z: int
    walls: tuple[float, ...] = ()
    lam: float | None = None
    rest: tuple[int, ...] = ()
    cells: int = 16

    def text(self) -> str:
        t = f"lambda={self.lam:g}" if self.kind == "lambda" else "walls=" + ",".join(f"{w:g}" for w in self.walls)
        return t + (f" rest={_cells_text(self.rest)}" if self.rest else "")

    def layout(self) -> tuple[float, ...]:
        """Wall positions: the target's own, or Z walls evenly spread (a wavelength target's reference layout)."""
        if self.kind == "walls":
            return self.walls
        n = self.cells
        return tuple(math.floor(n * (k + 0.5) / self.z) + 0.5 for k in range(self.z))

    def segments(self) -> np.ndarray:
        """Segment index of every cell (0-based): the domains between the layout's walls, each rest run its own."""
        seg = np.zeros(self.cells, dtype=int)
        walls = self.layout()
        for j in range(self.cells):
            seg[j] = sum(1 for w in walls if w < j + 1)
        if self.rest:
            top = seg.max() + 1
            for j in self.rest:
                seg[j - 1] = top
        _, seg = np.unique(seg, return_inverse=True)
        return seg


def _cells_text(cells: Sequence[int]) -> str:
    from metacell_common.cli import cells_text

    return cells_text(cells).replace(", ", ",").replace(" ", "")


def _cells_arg(text: str, n: int, what: str) -> tuple[int, ...]:
    out: list[int] = []
    for part in (p.strip() for p in str(text).split(",") if p.strip()):
        lo, sep, hi = part.partition("-")
        try:
            a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
        except ValueError:
            raise DesignError(f"{what} {text!r}: expected cell numbers or ranges such as 9-16") from None
        if not (1 <= a <= b <= n):
            raise DesignError(f"{what} {text!r}: cells must lie in 1..{n}")
        out += [j for j in range(a, b + 1) if j not in out]
    if not out:
        raise DesignError(f"{what} {text!r}: no cells")
    return tuple(sorted(out))


def parse_target(text: str, cells: int = 16, rest: str | Sequence[int] | None = None) -> Target:
    """`lambda=N` (N must fit the chain: Z = 2 (cells - 1) / N whole walls) or `walls=a.5,b.5,...`."""
    key, sep, val = str(text).partition("=")
    key = key.strip().lower()
    rest_cells = () if not rest else (_cells_arg(rest, cells, "--rest") if isinstance(rest, str) else tuple(rest))
    if not sep or key not in ("lambda", "walls"):
        raise DesignError(f"--target {text!r}: expected lambda=N (cells) or walls=A.5,B.5,...")
    if key == "lambda":
        try:
            lam = float(val)
        except ValueError:
            raise DesignError(f"--target {text!r}: lambda must be a number of cells") from None
        if not (math.isfinite(lam) and lam > 0):
            raise DesignError(f"--target {text!r}: lambda must be a positive number of cells")
        z = 2 * (cells - 1) / lam
        if rest_cells:
            raise DesignError("--rest: give the walls of the patterned part (walls=...), not a wavelength")
        if z < 0.999 or abs(z - round(z)) > 1e-3 * z or round(z) > cells - 1:
            fits = ", ".join(f"{2 * (cells - 1) / k:.4g}" for k in range(1, cells))
            raise DesignError(
                f"--target lambda={lam:g}: {z:.3g} walls do not fit {cells} cells (lambda = 2 (n - 1) / Z for Z "
                f"walls); the wavelengths that fit: {fits}"
            )
        z = int(round(z))
        return Target("lambda", z, (), 2 * (cells - 1) / z, rest_cells, cells)
    walls = []
    for w in val.split(","):
        try:
            x = float(w)
        except ValueError:
            raise DesignError(f"--target {text!r}: {w!r} is not a bond position such as 5.5") from None
        if not (abs(x - math.floor(x) - 0.5) < 1e-9 and 1 <= math.floor(x) <= cells - 1):
            raise DesignError(
                f"--target {text!r}: wall {w.strip()} must sit on a bond j.5 between cells j and j+1, 1 <= j <= "
                f"{cells - 1}"
            )
        walls.append(x)
    walls = sorted(set(walls))
    for c in rest_cells:
        if any(abs(c - w) < 1 for w in walls):
            raise DesignError(f"--rest: cell {c} borders a wall of the target; rest cells lie outside the pattern")
    return Target("walls", len(walls), tuple(walls), None, rest_cells, cells)


@dataclass(frozen=True)
class Push:
    cell: int
    sign: int  # +1 CCW, -1 CW


def parse_pushes(text: str | Sequence[int], cells: int = 16) -> tuple[Push, ...]:
    """`8`, `6,10`, `1:+,16:-` (CCW + by default): hand pushes on alpha of those cells."""
    if not isinstance(text, str):
        return tuple(Push(int(c), 1) for c in text)
    out = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        c, _, s = part.partition(":")
        try:
            cell = int(c)
        except ValueError:
            raise DesignError(f"--push {text!r}: expected CELL[:SIGN],... such as 8 or 1:+,16:-") from None
        if not 1 <= cell <= cells:
            raise DesignError(f"--push {text!r}: cell {cell} outside 1..{cells}")
        sign = {"": 1, "+": 1, "ccw": 1, "-": -1, "cw": -1}.get(s.strip().lower())
        if sign is None:
            raise DesignError(f"--push {text!r}: sign {s!r}: expected + (CCW) or - (CW)")
        out.append(Push(cell, sign))
    if not out or len({p.cell for p in out}) != len(out):
        raise DesignError(f"--push {text!r}: expected distinct cells")
    return tuple(out)


# ---- landing ------------------------------------------------------------------------------------------------


def final_walls(alpha: np.ndarray, rest: Sequence[int] = (), threshold: float = WALL_THRESHOLD_RAD) -> list[float]:
    """Bond positions of the sign changes of a final profile among its cells above `threshold` (rest cells left
    out), each at the zero of the straight line between the two cells, rounded to the nearest bond j + 0.5."""
    u = np.asarray(alpha, dtype=float)
    keep = [j for j in range(u.size) if abs(u[j]) > threshold and (j + 1) not in rest]
    out = []
    for a, b in zip(keep[:-1], keep[1:]):
        if np.sign(u[a]) != np.sign(u[b]):
            x = a + (b - a) * u[a] / (u[a] - u[b]) + 1.0  # 1-based position of the zero
            out.append(math.floor(x) + 0.5 if x % 1 else x + 0.5)
    return out


def domain_peaks(alpha: np.ndarray, walls: Sequence[float], rest: Sequence[int] = ()) -> list[float]:
    """The largest |alpha| of each domain (the cells between consecutive walls, rest cells left out)."""
    u = np.abs(np.asarray(alpha, dtype=float))
    edges = [0.5, *walls, u.size + 0.5]
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        cells = [j for j in range(1, u.size + 1) if lo < j < hi and j not in rest]
        if cells:
            out.append(float(u[[j - 1 for j in cells]].max()))
    return out


def miss_reason(target: Target, alpha: np.ndarray, steady: bool = True, torque_ok: bool = True) -> str | None:
    """Why a final profile does not land (lands' tests in order), or None when it lands: "moving" (not steady),
    "torque limit", "at rest", "rest cells moved", "walls" (other walls, or another number of them), "domain not
    filled" (a cell off the walls within 0.1 rad, or a domain below DOMAIN_MIN_RAD)."""
    u = np.asarray(alpha, dtype=float)
    if not steady:
        return "moving"
    if not torque_ok:
        return "torque limit"
    if np.abs(u).max() <= WALL_THRESHOLD_RAD:
        return "at rest"
    if target.rest and np.abs(u[[c - 1 for c in target.rest]]).max() > WALL_THRESHOLD_RAD:
        return "rest cells moved"
    w = final_walls(u, target.rest)
    if (len(w) != target.z) if target.kind == "lambda" else (tuple(w) != target.walls):
        return "walls"
    inner = [j - 1 for j in interior_cells(u.size, w, target.rest)]
    if (inner and np.abs(u[inner]).min() <= WALL_THRESHOLD_RAD) or min(
        domain_peaks(u, w, target.rest)
    ) < DOMAIN_MIN_RAD:
        return "domain not filled"
    return None


def interior_cells(n: int, walls: Sequence[float], rest: Sequence[int] = ()) -> list[int]:
    """The cells (1-based) that are neither beside a wall nor at rest: the ones a patterned domain must fill."""
    return [j for j in range(1, n + 1) if j not in rest and all(abs(j - w) > 0.5 for w in walls)]


def lands(target: Target, alpha: np.ndarray, steady: bool = True, torque_ok: bool = True) -> bool:
    """Does a final alpha profile (rad, cells 1..n) show the target? See the module docstring: steady, within the
    torque limit, the target's walls (or their number), every domain reaching DOMAIN_MIN_RAD and filled (each
    cell off the walls beyond the wall threshold), rest cells within the wall threshold (miss_reason's tests)."""
    return miss_reason(target, alpha, steady, torque_ok) is None


# ---- parameterisation -----------------------------------------------------------------------------------------


@dataclass
class Space:
    """The search vector: one value per global parameter, then one per segment of each per-cell parameter."""

    base: Params
    vary: tuple[str, ...]
    per_cell: tuple[str, ...]
    seg: np.ndarray
    names: list[str] = field(default_factory=list)
    bounds: list[tuple[float, float]] = field(default_factory=list)

    def __post_init__(self):
        nseg = int(self.seg.max()) + 1
        for k in self.vary:
            if k in self.per_cell:
                for s in range(nseg):
                    self.names.append(f"{k}[seg {s + 1}]")
                    self.bounds.append(BOUNDS[k])
            else:
                self.names.append(k)
                self.bounds.append(BOUNDS[k])

    def params(self, x: np.ndarray) -> Params:
        """Params of a search vector, rounded to the registers' resolution."""
        nseg = int(self.seg.max()) + 1
        kw: dict[str, Any] = {}
        i = 0
        for k in self.vary:
            if k in self.per_cell:
                vals = np.asarray(x[i : i + nseg])[self.seg]
                kw[k] = tuple(round(float(v), LSB_DIGITS) for v in vals)
                i += nseg
            else:
                kw[k] = round(float(x[i]), LSB_DIGITS)
                i += 1
        return dataclasses.replace(self.base, **kw)

    def x0(self) -> np.ndarray:
        """The base scene's values as a search vector (clipped into the box)."""
        out = []
        for k in self.vary:
            v = self.base.per_cell(k)
            reps = (
                [float(v[self.seg == s].mean()) for s in range(int(self.seg.max()) + 1)]
                if k in self.per_cell
                else [float(v.mean())]
            )
            out += [min(max(r, BOUNDS[k][0]), BOUNDS[k][1]) for r in reps]
        return np.array(out)


def _shape_ok(p: Params) -> bool:
    k1, k2 = p.per_cell("k1"), p.per_cell("k2")
    return bool(np.all(k1 > np.maximum(k2, 0.0) + 1e-3))


# ---- linear theory: the first guess ---------------------------------------------------------------------------


def linear_score(p: Params, target: Target) -> tuple[float, dict]:
    """(score, facts) of the chain's linear theory for the target: > 1 when the fastest mode is stationary, grows
    at least MIN_GROWTH_PER_S and has the target's walls (rest cells under a fifth of its peak); then 1 + gap,
    gap = (g1 - max(g2, 0)) / g1 in [0, 1]. Below 1: how far it is (walls off, growth, kind)."""
    from ..analysis.chain import chain_modes
    from ..analysis.stability import theory_of

    if not _shape_ok(p):
        return -3.0, {"why": "k1 <= max(k2, 0)"}
    res = chain_modes(p, theory_of("hil", p), count=2)
    top = res["modes"][0]
    g1 = top["growth_per_s"]
    g2 = res["modes"][1]["growth_per_s"] if len(res["modes"]) > 1 else -math.inf
    alpha = top["alpha"]
    walls = final_walls(alpha, target.rest, 0.1 * np.abs(alpha).max())
    facts = {
        "growth_per_s": g1,
        "next_growth_per_s": g2,
        "kind": top["kind"],
        "walls": walls,
        "mode_alpha": [float(v) for v in alpha],
    }
    if top["kind"] != "stationary":
        return -2.0 + 0.1 * math.tanh(-g1 / 50), facts
    if g1 < MIN_GROWTH_PER_S:
        return -1.0 + 0.5 * math.tanh(g1 / 20), facts
    miss: float
    if target.kind == "lambda":
        miss = abs(len(walls) - target.z)
    else:
        miss = len(set(walls) ^ set(target.walls)) + sum(
            min(abs(w - t) for w in walls) if walls else 1.0 for t in target.walls
        ) * (set(walls) != set(target.walls))
    if target.rest:
        r = np.abs(alpha[[c - 1 for c in target.rest]]).max() / np.abs(alpha).max()
        miss += max(0.0, r - 0.2) * 5
    if not miss:  # every cell off the walls carries a share of the mode's peak (no part of a domain near rest)
        inner = [j - 1 for j in interior_cells(alpha.size, walls, target.rest)]
        if inner:
            fill = float(np.abs(alpha[inner]).min() / np.abs(alpha).max())
            miss += max(0.0, DOMAIN_FILL_MODE - fill) * 4
    if miss:
        return 0.5 - 0.1 * miss, facts
    gap = (g1 - max(g2, 0.0)) / g1
    return 1.0 + gap, facts


def first_guess(space: Space, target: Target, seed: int = 1, maxiter: int = 60) -> tuple[np.ndarray, float, dict]:
    """Differential evolution on the linear score (scipy.optimize), from the base scene's values too."""
    from scipy.optimize import differential_evolution

    def f(x):
        return -linear_score(space.params(x), target)[0]

    rng = np.random.default_rng(seed)
    lo = np.array([b[0] for b in space.bounds])
    hi = np.array([b[1] for b in space.bounds])
    npop = max(15, 8 * len(lo))
    init = lo + (hi - lo) * rng.random((npop, len(lo)))
    init[0] = space.x0()
    r = differential_evolution(
        f, space.bounds, init=init, seed=seed, maxiter=maxiter, tol=1e-6, polish=False, updating="immediate"
    )
    x = np.asarray(r.x)
    score, facts = linear_score(space.params(x), target)
    return x, score, facts


# ---- ensembles -------------------------------------------------------------------------------------------------


def _scene_table(base_table: dict, p: Params, pushes: Sequence[Push], torque: float, duration: float) -> dict:
    t = json.loads(json.dumps(base_table))
    for k in REACTION_KEYS:
        v = getattr(p, k)
        t["params"][k] = list(v) if isinstance(v, tuple) else v
    t["perturbation"] = [
        {"cell": q.cell, "chain": "alpha", "torque_Nm": q.sign * torque, "start_s": 0.1, "duration_s": duration}
        for q in pushes
    ]
    return t


def noise_overrides(seed: int) -> list[str]:
    """The --set items of the noise model with this seed (what a verification run uses)."""
    return [f"model_options.noise.seed={seed}"] + [f"model_options.noise.{k}={v}" for k, v in NOISE.items()]


def _noise(t: dict, seed: int | None) -> dict:
    t = json.loads(json.dumps(t))
    nz = t.setdefault("model_options", {}).setdefault("noise", {})
    if seed is None:
        for k in NOISE:
            nz[k] = 0.0
    else:
        nz.update(NOISE)
        nz["seed"] = seed
    return t


def run_tables(tables: list[dict]) -> list[dict]:
    """Run scene tables as one batched hil ensemble (workbench.batch); per run {final_alpha, final_beta, steady}
    or {error}. The Dask task of a design's search."""
    from ..analysis.observables import is_steady
    from ..scene import scene_from_dict
    from .batch import run_batch

    scenes = [scene_from_dict(t) for t in tables]
    out: list[dict[str, Any]] = []
    for r in run_batch(scenes, errors="return"):
        if isinstance(r, BaseException):
            out.append({"error": f"{type(r).__name__}: {r}"})
            continue
        out.append(
            {
                "final_alpha": r.alpha[-1].tolist(),
                "final_beta": r.beta[-1].tolist(),
                "steady": is_steady(r.t, r.alpha, r.beta),
            }
        )
    return out


class Runner:
    """Runs lists of scene tables: in this process, or chunked over a Dask cluster (--scheduler)."""

    def __init__(self, scheduler: str | None = None) -> None:
        self.client = None
        self.runs = 0
        if scheduler:
            from distributed import Client

            self.client = Client(scheduler, timeout="20s")

    def __call__(self, tables: list[dict]) -> list[dict]:
        self.runs += len(tables)
        if self.client is None:
            return run_tables(tables)
        nw = max(1, len(self.client.scheduler_info().get("workers", {})))
        size = max(1, math.ceil(len(tables) / (2 * nw)))
        chunks = [tables[i : i + size] for i in range(0, len(tables), size)]
        futs = self.client.map(run_tables, chunks, pure=False, retries=2)
        return [r for part in self.client.gather(futs) for r in part]

    def close(self) -> None:
        if self.client is not None:
            self.client.close()


def torque_ok(p: Params, alpha: np.ndarray, beta: np.ndarray) -> bool:
    """The reaction torques of a final state within the drivers' limit kt * vmax (5.86 V: 44 mN m)."""
    from ..physics import reaction

    ra, rb = reaction(p, np.asarray(alpha), np.asarray(beta))
    return bool(max(np.abs(ra).max(), np.abs(rb).max()) <= p.kt * p.vmax_v)


def closeness(target: Target, alpha: np.ndarray) -> float:
    """How near a missed run's final pattern came, in [0, 1]: half for its walls (the share of the target's walls
    it has on their bonds among all it has; for a wavelength 1 - |Z - Z_target| / Z_target), half for how much of
    the chain the pattern fills (the share of the cells off the target's walls beyond the wall threshold). The
    search's partial credit, so that it can climb while nothing lands yet."""
    u = np.asarray(alpha, dtype=float)
    w = final_walls(u, target.rest)
    if target.kind == "lambda":
        walls = max(0.0, 1.0 - abs(len(w) - target.z) / target.z)
        inner = interior_cells(u.size, w, target.rest)
    else:
        walls = len(set(w) & set(target.walls)) / (len(target.walls) + len(set(w) - set(target.walls)))
        inner = interior_cells(u.size, target.walls, target.rest)
    fill = float(np.mean(np.abs(u[[j - 1 for j in inner]]) > WALL_THRESHOLD_RAD)) if inner else 1.0
    return 0.5 * walls + 0.5 * fill


def _landed(target: Target, p: Params, r: dict) -> bool:
    if "error" in r:
        return False
    a = np.asarray(r["final_alpha"])
    return lands(target, a, bool(r["steady"]), torque_ok(p, a, np.asarray(r["final_beta"])))


# ---- the design ---------------------------------------------------------------------------------------------


def _search_tables(base_table, p, pushes, seeds: int) -> list[dict]:
    t = [_noise(_scene_table(base_table, p, pushes, *NOMINAL_PUSH), SEARCH_SEED0 + s) for s in range(seeds)]
    t += [_noise(_scene_table(base_table, p, pushes, tq, du), None) for tq, du in SEARCH_PUSHES]
    return t


def hil_search(
    space: Space,
    target: Target,
    pushes: Sequence[Push],
    base_table: dict,
    x0: np.ndarray,
    runner: Runner,
    *,
    seeds: int = 8,
    maxiter: int = 8,
    popsize: int = 10,
    seed: int = 1,
    report: Callable[[str], None] = lambda s: None,
) -> tuple[np.ndarray, float, list[dict]]:
    """Differential evolution over batched hil ensembles (module docstring, step 2); returns (x, score, history)."""
    from scipy.optimize import differential_evolution

    history: list[dict] = []
    per = seeds + len(SEARCH_PUSHES)
    done = [False]  # some candidate landed in every search and check run

    def scores(xs: np.ndarray) -> np.ndarray:
        """Per candidate: the mean over its runs of 1 (landed) or CLOSE_WEIGHT x closeness, + the linear margin."""
        fracs: list[float] = []
        ps = [space.params(x) for x in xs]
        lin = [linear_score(p, target) for p in ps]
        tables = []
        for p in ps:
            tables += _search_tables(base_table, p, pushes, seeds) if _shape_ok(p) else []
        res = runner(tables) if tables else []
        out, k = [], 0
        for p, (ls, _) in zip(ps, lin):
            if not _shape_ok(p):
                out.append(-1.0)
                continue
            rr = res[k : k + per]
            k += per
            hits = [_landed(target, p, r) for r in rr]
            part = [
                1.0
                if h
                else (CLOSE_WEIGHT * closeness(target, np.asarray(r["final_alpha"])) if "error" not in r else 0.0)
                for h, r in zip(hits, rr)
            ]
            frac = float(np.mean(hits))
            if all(hits):  # every search run landed: the same again on fresh seeds, so one lucky set is not enough
                check = runner(
                    [_noise(_scene_table(base_table, p, pushes, *NOMINAL_PUSH), CHECK_SEED0 + s) for s in range(per)]
                )
                more = [_landed(target, p, r) for r in check]
                part += [1.0 if h else 0.0 for h in more]
                frac = float(np.mean(hits + more))
                if all(more):
                    done[0] = True
                    part.append(1.0 + FULL_BONUS * len(part))  # (a mean over part: + FULL_BONUS, above any miss)
            gap = max(0.0, min(1.0, ls - 1.0)) if ls > 1 else 0.0
            out.append(float(np.mean(part)) + MARGIN_WEIGHT * gap)
            history.append({"fraction": frac, "linear_gap": gap})
            fracs.append(frac)
        report(f"hil search: {len(xs)} candidate(s) x {per} runs, best fraction landing {max(fracs, default=0):.3f}")
        return np.array(out)

    s0 = scores(np.array([x0]))[0]
    if done[0]:
        return x0, float(s0), history
    lo = np.array([b[0] for b in space.bounds])
    hi = np.array([b[1] for b in space.bounds])
    rng = np.random.default_rng(seed)
    init = np.clip(x0 + 0.12 * (hi - lo) * rng.standard_normal((popsize, len(lo))), lo, hi)
    init[0] = x0
    best = {"x": x0, "s": s0}

    def f(xt):  # vectorized: xt has shape (dims, candidates)
        sc = scores(xt.T)
        i = int(np.argmax(sc))
        if sc[i] > best["s"]:
            best["x"], best["s"] = xt.T[i].copy(), float(sc[i])
        return -sc

    def stop(*_a, **_k):
        return done[0]

    differential_evolution(
        f,
        space.bounds,
        init=init,
        seed=seed,
        maxiter=maxiter,
        polish=False,
        vectorized=True,
        updating="deferred",
        callback=stop,
        tol=0.0,
        atol=-1.0,  # never "converged": a population that all misses alike must keep searching (until maxiter)
    )
    return np.asarray(best["x"]), float(best["s"]), history


def verify(scene_path: Path, target: Target, runner: Runner, seeds: int = 20, *, pushes_too: bool = True) -> dict:
    """Run the written scene file as `run` loads it: `seeds` noise seeds (VERIFY_SEED0..) and, with pushes_too, every
    push of the documented range (no noise); the fraction of each that lands, and every run's walls."""
    from ..physics import reaction
    from ..scene import load_scene, scene_table

    sc = load_scene(str(scene_path))
    p = sc.params
    base = scene_table(sc)
    tables = [_noise(base, VERIFY_SEED0 + s) for s in range(seeds)]
    grid = [(tq, du) for tq in PUSH_TORQUES_NM for du in PUSH_DURATIONS_S] if pushes_too else []
    for tq, du in grid:
        t = _noise(base, None)
        for q in t["perturbation"]:
            q["torque_Nm"] = math.copysign(tq, q["torque_Nm"])
            q["duration_s"] = du
        tables.append(t)
    res = runner(tables)
    cap = p.kt * p.vmax_v
    runs = []
    for i, r in enumerate(res):
        what = (
            {"seed": VERIFY_SEED0 + i}
            if i < seeds
            else {"torque_Nm": grid[i - seeds][0], "duration_s": grid[i - seeds][1]}
        )
        if "error" in r:
            runs.append({**what, "landed": False, "error": r["error"]})
            continue
        a, b = np.asarray(r["final_alpha"]), np.asarray(r["final_beta"])
        ra, rb = reaction(p, a, b)
        why = miss_reason(target, a, bool(r["steady"]), torque_ok(p, a, b))
        runs.append(
            {
                **what,
                "landed": why is None,
                "why": why,
                "walls": final_walls(a, target.rest),
                "steady": bool(r["steady"]),
                "torque_fraction": float(max(np.abs(ra).max(), np.abs(rb).max()) / cap),
                "final_alpha_rad": [round(float(v), 4) for v in a],
            }
        )
    fs = float(np.mean([r["landed"] for r in runs[:seeds]])) if seeds else None
    fp = float(np.mean([r["landed"] for r in runs[seeds:]])) if grid else None
    return {
        "seeds": seeds,
        "noise": NOISE,
        "fraction_seeds": fs,
        "push_torques_Nm": list(PUSH_TORQUES_NM) if grid else [],
        "push_durations_s": list(PUSH_DURATIONS_S) if grid else [],
        "fraction_pushes": fp,
        "max_torque_fraction": max((r.get("torque_fraction", 0.0) for r in runs), default=0.0),
        "runs": runs,
    }


def _neighbours(t: Target, cells: int) -> list[Target]:
    """Targets near t, nearest first: every other wall count by its wavelength's distance; the layouts with one
    wall moved by one or two bonds (one bond first)."""
    if t.kind == "lambda":
        zs = sorted((z for z in range(1, cells) if z != t.z), key=lambda z: abs(2 * (cells - 1) / z - (t.lam or 0)))
        return [Target("lambda", z, (), 2 * (cells - 1) / z, (), cells) for z in zs]
    out = []
    for step in (1.0, 2.0):
        for i in range(len(t.walls)):
            for d in (-step, step):
                w = list(t.walls)
                w[i] += d
                if (
                    1.5 <= w[i] <= cells - 0.5
                    and len(set(w)) == len(w)
                    and not any(abs(c - x) < 1 for c in t.rest for x in w)
                ):
                    out.append(Target("walls", len(w), tuple(sorted(w)), None, t.rest, cells))
    return list(dict.fromkeys(out))


MAX_NEAREST_VERIFIED = 6  # neighbours verified with the firmware in the loop at most (those with a linear score > 1)


def nearest_reachable(
    target: Target,
    base: Params,
    vary,
    per_cell,
    pushes,
    base_table: dict,
    runner: Runner,
    outp: Path,
    *,
    seeds: int,
    require: float,
    seed: int,
    report: Callable[[str], None],
    search_seeds: int = 8,
    maxiter: int = 8,
) -> dict | None:
    """The nearest target (_neighbours' order) whose linear first guess has the target's mode (score > 1) and whose
    design (first guess, then the hil search) lands in `require` of `seeds` noise seeds; its scene is left as
    nearest_scene.toml. None if none of the first MAX_NEAREST_VERIFIED such candidates does."""
    verified = 0
    for cand in _neighbours(target, target.cells):
        sp = space_for(base, vary, per_cell, cand)
        xc, lc, _ = first_guess(sp, cand, seed)
        if lc <= 1.0:
            report(f"nearest: {cand.text()} has no linear first guess (score {lc:.2f})")
            continue
        xc, _, _ = hil_search(
            sp, cand, pushes, base_table, xc, runner, seeds=search_seeds, maxiter=maxiter, seed=seed, report=report
        )
        pc = sp.params(xc)
        cpath = outp / "nearest_scene.toml"
        _write_scene(cpath, base_table, pc, pushes, cand, "nearest_" + cand.text().replace("=", "_"))
        vc = verify(cpath, cand, runner, seeds, pushes_too=False)
        verified += 1
        report(f"nearest: {cand.text()} lands in {vc['fraction_seeds']:.2f} of the seeds")
        if vc["fraction_seeds"] >= require:
            return {
                "target": cand.text(),
                "fraction_seeds": vc["fraction_seeds"],
                "params": _params_doc(pc),
                "scene": cpath.name,
            }
        cpath.unlink()
        if verified >= MAX_NEAREST_VERIFIED:
            break
    return None


def _write_scene(path: Path, base_table: dict, p: Params, pushes, target: Target, name: str) -> None:
    import tomli_w

    t = _scene_table(base_table, p, pushes, *NOMINAL_PUSH)
    defaults = dataclasses.asdict(Params(cells=p.cells))
    t["params"] = {k: v for k, v in t["params"].items() if k in REACTION_KEYS or v != defaults.get(k)}
    t["name"] = name
    t["description"] = (
        f"designed for {target.text()} with push(es) on "
        + ", ".join(f"alpha_{q.cell} ({'CCW' if q.sign > 0 else 'CW'})" for q in pushes)
        + " (python -m host_emulator design, docs/design.md)"
    )
    t["model"] = "hil"
    t.get("model_options", {}).pop("noise", None)
    head = (
        f"# Scene written by `python -m host_emulator design` (docs/design.md): target {target.text()}.\n"
        f"# Run it: python -m host_emulator run {path}\n"
        f"# On the rig: python -m metacell_tools.experiment run {path} -c PORT@115200 (or `rehearse`)\n"
    )
    path.write_text(head + tomli_w.dumps(t))


def plot_design(doc: dict, target: Target, path: Path) -> None:
    """design.png: the verification runs' final profiles against the target, and the designed parameters."""
    from matplotlib.figure import Figure

    n = target.cells
    cells = np.arange(1, n + 1)
    fig = Figure(figsize=(8.0, 6.2))
    ax, bx = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    runs = doc["verification"]["runs"]
    for r in runs:
        if "final_alpha_rad" in r:
            ax.plot(cells, r["final_alpha_rad"], color="C0" if r["landed"] else "C3", lw=0.7, alpha=0.6)
    amp = np.median([np.abs(r["final_alpha_rad"]).max() for r in runs if "final_alpha_rad" in r] or [0.6])
    mode = np.asarray(doc["linear_theory"]["mode_alpha"])
    ax.plot(cells, amp * mode, "k--", lw=1.2, label="linear theory: fastest mode (scaled)")
    for w in target.layout() if target.kind == "walls" else ():
        ax.axvline(w, color="k", lw=1.0)
    for c in target.rest:
        ax.axvspan(c - 0.5, c + 0.5, color="0.85", lw=0)
    v = doc["verification"]
    ax.plot([], [], color="C0", label="landed")
    ax.plot([], [], color="C3", label="missed")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_ylabel("final alpha (rad)")
    ax.set_title(
        f"target {target.text()}, push {doc['push_text']}: lands in {v['fraction_seeds'] * 100:.0f} % of "
        f"{v['seeds']} noise seeds, {100 * (v['fraction_pushes'] or 0):.0f} % of the pushes (hil)",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="lower right")
    for k in doc["vary"]:
        vals = np.broadcast_to(np.asarray(doc["params"][k], dtype=float), (n,))
        bx.step(cells, vals, where="mid", label=k)
    for q in doc["pushes"]:
        bx.axvline(q["cell"], color="0.6", ls=":", lw=1)
    bx.set_xlabel("cell")
    bx.set_ylabel("N m/rad (alpha*: rad)")
    bx.legend(fontsize=7, ncol=3)
    bx.set_xticks(cells)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _params_doc(p: Params) -> dict:
    return {k: (list(getattr(p, k)) if isinstance(getattr(p, k), tuple) else getattr(p, k)) for k in REACTION_KEYS}


def design(
    target: str,
    push: str | Sequence[int] | None = None,
    *,
    scene: str = "default",
    vary: Sequence[str] = ("sigma", "k_ab", "k2"),
    per_cell: Sequence[str] | None = None,
    rest: str | Sequence[int] | None = None,
    seeds: int = 20,
    search_seeds: int = 8,
    maxiter: int = 8,
    require: float = REQUIRE,
    nearest: bool = True,
    out: str | Path = "out/design",
    scheduler: str | None = None,
    seed: int = 1,
    quiet: bool = True,
) -> dict:
    """Design parameters for a target pattern (module docstring); writes design.json, scene.toml and design.png in
    `out` and returns design.json's content. per_cell None: none for a wavelength, sigma and k2 for a wall layout.
    Raises DesignError (bad input)."""
    from ..provenance import provenance
    from ..scene import load_scene, scene_table

    report = (lambda s: None) if quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    t0 = time.perf_counter()
    try:
        base = load_scene(scene, ["model=hil"])
    except (ValueError, KeyError, OSError) as e:
        raise DesignError(f"--scene {scene!r}: {e}") from None
    n = base.cells
    tgt = parse_target(target, n, rest)
    if push is None:
        pushes = tuple(Push(q.cell, 1 if q.torque_Nm >= 0 else -1) for q in base.perturbations if q.chain == "alpha")
        if not pushes:
            raise DesignError(f"--push: scene {scene!r} has no push on alpha; give --push CELL[:SIGN],...")
    else:
        pushes = parse_pushes(push, n)
    vary = tuple(dict.fromkeys(vary))
    bad = [k for k in vary if k not in REACTION_KEYS]
    if bad or not vary:
        raise DesignError(f"--vary {','.join(vary)}: expected names among {', '.join(REACTION_KEYS)}")
    if per_cell is None:
        per_cell = (
            () if tgt.kind == "lambda" and not tgt.rest else tuple(k for k in ("sigma", "k_ab", "k2") if k in vary)
        )
    per_cell = tuple(dict.fromkeys(per_cell))
    if any(k not in vary for k in per_cell):
        raise DesignError(f"--per-cell {','.join(per_cell)}: each must also be in --vary ({','.join(vary)})")
    if not (1 <= seeds <= 1000 and 1 <= search_seeds <= 1000 and 0 <= maxiter <= 1000 and 0 < require <= 1):
        raise DesignError("seeds and search seeds in 1..1000, maxiter in 0..1000, require in (0, 1]")
    from ..outpaths import check_out_dir

    outp = Path(out)
    why = check_out_dir(outp)
    if why:
        raise DesignError(why)
    base_table = scene_table(base)
    base_table["model"] = "hil"
    runner = Runner(scheduler)
    try:
        space = Space(base.params, vary, per_cell, tgt.segments())
        report(f"design {tgt.text()}: linear theory over {', '.join(space.names)}")
        x_lin, lin, facts = first_guess(space, tgt, seed)
        report(f"first guess: linear score {lin:.3f} (> 1: the fastest mode has the target's walls)")
        x, score, hist = hil_search(
            space,
            tgt,
            pushes,
            base_table,
            x_lin,
            runner,
            seeds=search_seeds,
            maxiter=maxiter,
            seed=seed,
            report=report,
        )
        p = space.params(x)
        lin2, facts2 = linear_score(p, tgt)
        name = "design_" + tgt.text().replace("=", "_").replace(",", "_").replace(" ", "_")
        scene_path = outp / "scene.toml"
        _write_scene(scene_path, base_table, p, pushes, tgt, name)
        report(f"verifying {scene_path}: {seeds} noise seeds and {len(PUSH_TORQUES_NM) * len(PUSH_DURATIONS_S)} pushes")
        ver = verify(scene_path, tgt, runner, seeds)
        reached = bool(ver["fraction_seeds"] >= require)
        near = None
        if not reached and nearest:
            near = nearest_reachable(
                tgt,
                base.params,
                vary,
                per_cell,
                pushes,
                base_table,
                runner,
                outp,
                seeds=seeds,
                require=require,
                seed=seed,
                report=report,
                search_seeds=search_seeds,
                maxiter=maxiter,
            )
        doc: dict[str, Any] = {
            "target": tgt.text(),
            "target_kind": tgt.kind,
            "domain_walls": tgt.z,
            "walls": list(tgt.walls) if tgt.kind == "walls" else None,
            "lambda_cells": tgt.lam,
            "rest_cells": list(tgt.rest),
            "cells": n,
            "pushes": [{"cell": q.cell, "sign": q.sign} for q in pushes],
            "push_text": ",".join(f"{q.cell}:{'+' if q.sign > 0 else '-'}" for q in pushes),
            "push_nominal": {"torque_Nm": NOMINAL_PUSH[0], "duration_s": NOMINAL_PUSH[1], "start_s": 0.1},
            "base_scene": base.name,
            "vary": list(vary),
            "per_cell": list(per_cell),
            "segments": [int(s) + 1 for s in tgt.segments()],
            "params": _params_doc(p),
            "linear_theory": {
                "theory": "hil: eigenmodes of the chain, lattice with inertia + the motors' back-EMF damping",
                "score": lin2,
                "first_guess_score": lin,
                "growth_per_s": facts2.get("growth_per_s"),
                "next_growth_per_s": facts2.get("next_growth_per_s"),
                "kind": facts2.get("kind"),
                "mode_walls": facts2.get("walls"),
                "mode_alpha": facts2.get("mode_alpha"),
            },
            "verification": ver,
            "reached": reached,
            "require": require,
            "nearest_reachable": near,
            "search": {
                "optimizer": "scipy.optimize.differential_evolution (linear theory, then batched hil ensembles)",
                "search_seeds": search_seeds,
                "search_pushes": [list(x) for x in SEARCH_PUSHES],
                "search_score": score,
                "candidates_scored": len(hist),
                "hil_runs": runner.runs,
                "scheduler": scheduler,
                "wall_s": time.perf_counter() - t0,
            },
            "files": ["design.json", "scene.toml", "design.png"] + (["nearest_scene.toml"] if near else []),
            "provenance": provenance(),
        }
    finally:
        runner.close()
    plot_design(doc, tgt, outp / "design.png")
    from ..analysis.summary import clean

    doc = clean(doc)
    (outp / "design.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return doc


def space_for(base: Params, vary, per_cell, target: Target) -> Space:
    return Space(base, tuple(vary), tuple(per_cell), target.segments())


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
        "then: python -m host_emulator run out/design_l10/scene.toml\n"
        "      python -m metacell_tools.rigtools.command -c PORT@115200 apply out/design_l10/design.json\n"
        "exit codes: 0 the target is reached (>= --require of the noise seeds), 2 bad input, 3 not reached "
        "(design.json names the nearest reachable target).",
    )
    ap.add_argument("--target", required=True, help="lambda=N (cells; Z = 2(n-1)/N walls) or walls=A.5,B.5,...")
    ap.add_argument(
        "--push",
        default=None,
        help="CELL[:SIGN],... hand pushes on alpha, + CCW (default) or - CW (default: the scene's pushes)",
    )
    ap.add_argument("--rest", default=None, metavar="CELLS", help="cells that must end at rest, e.g. 9-16")
    ap.add_argument("--scene", default="default", help="scene giving everything not designed (default: default)")
    ap.add_argument("--vary", default="sigma,k_ab,k2", help="parameters the design may change (default sigma,k_ab,k2)")
    ap.add_argument(
        "--per-cell",
        default=None,
        help="of those, the ones that may differ between the target's domains (default: none for lambda=, "
        "sigma,k_ab,k2 for walls=; 'none' for none)",
    )
    ap.add_argument("--seeds", type=int, default=20, help="noise seeds of the verification (default 20)")
    ap.add_argument("--search-seeds", type=int, default=8, help="noise seeds per candidate in the search (default 8)")
    ap.add_argument("--maxiter", type=int, default=8, help="generations of the hil search (default 8)")
    ap.add_argument("--require", type=float, default=REQUIRE, help="fraction of seeds that must land (default 0.9)")
    ap.add_argument("--no-nearest", action="store_true", help="do not look for the nearest reachable target")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler address: the hil ensembles run there")
    ap.add_argument("--out", default=None, help="output directory (default out/design_<target>)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines")
    args = ap.parse_args(argv)
    per = None if args.per_cell is None else (() if args.per_cell == "none" else tuple(args.per_cell.split(",")))
    out = args.out or "out/design_" + args.target.replace("=", "_").replace(",", "_")
    try:
        doc = design(
            args.target,
            args.push,
            scene=args.scene,
            vary=tuple(v.strip() for v in args.vary.split(",") if v.strip()),
            per_cell=per,
            rest=args.rest,
            seeds=args.seeds,
            search_seeds=args.search_seeds,
            maxiter=args.maxiter,
            require=args.require,
            nearest=not args.no_nearest,
            out=out,
            scheduler=args.scheduler,
            quiet=args.quiet,
        )
    except DesignError as e:
        print(f"design: error: {e}", file=sys.stderr)
        return 2
    v = doc["verification"]
    print(
        f"design {doc['target']} (push {doc['push_text']}): lands in {100 * v['fraction_seeds']:.0f} % of "
        f"{v['seeds']} noise seeds and {100 * (v['fraction_pushes'] or 0):.0f} % of "
        f"{len(v['push_torques_Nm']) * len(v['push_durations_s'])} pushes (hil, scene.toml as run loads it); "
        f"{doc['search']['hil_runs']} hil runs, {doc['search']['wall_s']:.0f} s"
    )
    for k in doc["vary"]:
        val = doc["params"][k]
        print(f"  {k}: " + (" ".join(f"{x:.4g}" for x in val) if isinstance(val, list) else f"{val:.6g}"))
    if not doc["reached"]:
        near = doc["nearest_reachable"]
        print(
            f"NOT REACHED: below {100 * doc['require']:.0f} % of the seeds; nearest reachable: "
            + (f"{near['target']} ({100 * near['fraction_seeds']:.0f} %)" if near else "none found nearby")
        )
    print(f"wrote {out}/design.json, scene.toml, design.png")
    return 0 if doc["reached"] else 3
