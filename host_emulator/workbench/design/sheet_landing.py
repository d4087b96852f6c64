"""Does a run on a sheet land on its target: a steady pattern filling the pattern region (of the target's wavelength
when it names one), the rest region at rest, no reaction torque beyond the drivers' cap; how near a miss came."""

from __future__ import annotations

import numpy as np

from ...analysis import pattern2d
from ...analysis.observables import WALL_THRESHOLD_RAD
from ...topology import Topology
from .constants import DOMAIN_MIN_RAD
from .sheet_target import SheetTarget

# a named wavelength lands when the pattern region's dominant wavelength is within this share of it (the structure
# factor of an 8-cell-wide region resolves wavelengths only to about a quarter)
LAMBDA_TOL = 0.25


def region_measures(target: SheetTarget, alpha: np.ndarray) -> dict:
    """pattern2d's measures of a final field's pattern region: of the rectangle itself when the region is one (its
    own open sheet), else of the whole sheet with the rest region set to 0."""
    u = np.asarray(alpha, dtype=float)
    box = target.pattern_box()
    if box is not None:
        g = target.topology.grid(u)[box]
        top = Topology(g.shape, "square", False)
        u = g.reshape(-1)
    else:
        top = target.topology
        u = np.where(target.rest_mask(), 0.0, u)
    return pattern2d.measures(np.array([0.0, 1.0]), np.stack([u, u]), top)


def interior_cells(target: SheetTarget, alpha: np.ndarray) -> np.ndarray:
    """(n,) bool: the pattern region's cells a pattern must fill, i.e. those beside neither a wall (a bonded
    neighbour of the other sign, both beyond the wall threshold or not) nor the rest region."""
    u = np.asarray(alpha, dtype=float)
    rest = target.rest_mask()
    keep = ~rest
    b = target.topology.bonds
    i, j = b[:, 0], b[:, 1]
    edge = (rest[i] != rest[j]) | ((np.sign(u[i]) != np.sign(u[j])) & ~rest[i] & ~rest[j])
    keep[i[edge]] = False
    keep[j[edge]] = False
    return keep & ~rest


def sheet_miss_reason(
    target: SheetTarget, alpha: np.ndarray, steady: bool = True, torque_ok: bool = True
) -> str | None:
    """Why a final field (cells in order) misses the target, or None when it lands; the tests in order: "moving"
    (not steady), "torque limit", "rest region moved" (a rest cell beyond 0.1 rad), "at rest" (the pattern region's
    largest |alpha| below DOMAIN_MIN_RAD, or pattern2d reads it as rest), "region not filled" (a cell of the pattern
    region beside neither a wall nor the rest region within 0.1 rad), "wavelength" (a named wavelength: the region's
    dominant one missing or beyond LAMBDA_TOL of it)."""
    u = np.asarray(alpha, dtype=float)
    if not steady:
        return "moving"
    if not torque_ok:
        return "torque limit"
    rest = target.rest_mask()
    if np.abs(u[rest]).max() > WALL_THRESHOLD_RAD:
        return "rest region moved"
    if np.abs(u[~rest]).max() < DOMAIN_MIN_RAD:
        return "at rest"
    m = region_measures(target, u)
    if m["pattern_kind"] in ("rest", "oscillation"):
        return "at rest" if m["pattern_kind"] == "rest" else "moving"
    inner = interior_cells(target, u)
    if inner.any() and np.abs(u[inner]).min() <= WALL_THRESHOLD_RAD:
        return "region not filled"
    if target.lam is not None:
        lam = m["dominant_wavelength_cells"]
        if lam is None or abs(lam - target.lam) > LAMBDA_TOL * target.lam:
            return "wavelength"
    return None


def sheet_lands(target: SheetTarget, alpha: np.ndarray, steady: bool = True, torque_ok: bool = True) -> bool:
    """Does the final field land (sheet_miss_reason is None)?"""
    return sheet_miss_reason(target, alpha, steady, torque_ok) is None


def sheet_closeness(target: SheetTarget, alpha: np.ndarray) -> float:
    """How near a missed run came, in [0, 1]: half the share of the rest region within 0.1 rad, half the share of
    the pattern region beyond it (the search's partial credit)."""
    u = np.abs(np.asarray(alpha, dtype=float))
    rest = target.rest_mask()
    return 0.5 * float(np.mean(u[rest] <= WALL_THRESHOLD_RAD)) + 0.5 * float(np.mean(u[~rest] > WALL_THRESHOLD_RAD))
