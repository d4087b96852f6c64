"""Does a run land on the target: its final walls, filled domains, rest cells and torques; how near a miss came."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...analysis.observables import WALL_THRESHOLD_RAD, domain_wall_bonds
from ...params import Params
from ...physics import reaction
from .constants import DOMAIN_MIN_RAD
from .target import Target


def final_walls(alpha: np.ndarray, rest: Sequence[int] = (), threshold: float = WALL_THRESHOLD_RAD) -> list[float]:
    """Bond positions of the sign changes of a final profile among its cells above `threshold` (rest cells left
    out), each at the zero of the straight line between the two cells, rounded to the nearest bond j + 0.5."""
    return domain_wall_bonds(alpha, threshold_rad=threshold, skip=rest)


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
    """Does a final alpha profile (rad, cells 1..n) show the target? See the package docstring: steady, within the
    torque limit, the target's walls (or their number), every domain reaching DOMAIN_MIN_RAD and filled (each
    cell off the walls beyond the wall threshold), rest cells within the wall threshold (miss_reason's tests)."""
    return miss_reason(target, alpha, steady, torque_ok) is None


def torque_ok(p: Params, alpha: np.ndarray, beta: np.ndarray) -> bool:
    """The reaction torques of a final state within the drivers' limit kt * vmax (5.86 V: 44 mN m)."""
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
