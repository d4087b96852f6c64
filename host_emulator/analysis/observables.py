"""Observables of a run (docs/physics.md#experiments): steadiness, spatial and temporal period, amplitude, growth rate.

Definitions (t in s, alpha/beta (T, N) in rad, cells j = 1..N at x_j = j - 1/2):

* steady: over the final window W (default: last 10 % of the run, at least 3 samples) every cell of both
  chains moves less than tol_rad peak-to-peak: max_j (max_W - min_W) < tol_rad.
* pattern_period_cells: the final alpha profile u_j minus its mean is fitted, for each wavenumber kappa in
  [pi/N, pi] (wavelengths 2..2N cells), by least squares with A cos(kappa x_j) + B sin(kappa x_j); the
  kappa explaining most variance (grid, then refined) gives lambda = 2 pi / kappa. None when the profile
  is flat (peak-to-peak < tol_rad).
* oscillation_period_s: reported only when the final window W shows the motion (the run is not steady and the
  last crossing below lies in W: ringing that has died out before the end is no oscillation). On the cell that
  moves most after the peak excursion, y = alpha - (median over W),
  zero crossings with hysteresis (|y| must exceed the band on each side) are located by linear
  interpolation; with >= 3 crossings c_0..c_n, period = 2 (c_k - c_0) / k with k the largest even index
  (same-direction crossings, so an offset reference does not bias it). None otherwise.
* amplitude_rad: max_j |alpha_j(t_end)|.
* growth_rate_per_s: A(t) = max_j |alpha_j(t)| (distance from rest). On the rise of A to 0.2 max A (the linear
  regime, before saturation), the contiguous rise of A ending there; log A is fitted by a straight line
  over its upper two decades (at least 5 samples, A rising by at least 3x); the slope is reported when the
  fit is good (R^2 > 0.98), else None.

How the source paper reads a pattern (its convention, reported beside the least-squares period):

* at_rest: over the final window every |alpha_j| and |beta_j| stays within ``rest_tol_rad`` (default 3
  encoder counts, 3 * 2 pi / 400 = 0.047 rad). A run at rest has no pattern: pattern_period_cells,
  pattern_wavelength_cells and dominant_mode are None and domain_walls is 0.
* domain_walls Z: the number of sign changes of the final alpha profile, counted only among the cells
  with |alpha_j| > ``wall_threshold_rad`` (default 0.1 rad, about 6 encoder counts: far below a
  pattern's amplitude of 0.5-0.7 rad, far above encoder quantisation), so a cell sitting near zero
  inside a wall neither adds nor hides a wall.
* pattern_wavelength_cells = 2 (N - 1) / Z: the wavelength in lattice spacings over the N - 1 spacings
  of the chain (30 / Z for 16 cells: one full period across the chain is 15, one and a half is 10,
  two is 7.5); None when Z = 0.
* domain_wall_bonds: where the Z walls are: for each, the bond between cells j and j + 1 written j + 1/2 (as
  design's targets are), at the zero of the straight line between the two cells of the sign change, rounded
  to the nearest bond; [] at rest.
* dominant_mode m: the free-end chain's linear modes are cos(pi m (j - 1/2) / N), m = 0..N-1 (wavelength
  2N/m cells); m is the index of the largest coefficient of the orthonormal cosine transform (DCT-II)
  of the final alpha profile; dominant_mode_lambda_cells = 2N/m (None for m = 0, the uniform mode).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from protocol.codec import RAD_PER_COUNT

__all__ = [
    "observables",
    "spatial_period",
    "temporal_period",
    "growth_rate",
    "is_steady",
    "domain_walls",
    "domain_wall_bonds",
    "dominant_mode",
    "is_at_rest",
]

ENCODER_STEP_RAD = RAD_PER_COUNT  # one encoder count (protocol/definition.py COUNTS_PER_REV)
DEFAULT_TOL_RAD = 2 * ENCODER_STEP_RAD  # two encoder counts
REST_TOL_RAD = 3 * ENCODER_STEP_RAD  # at rest: within three encoder counts of zero
WALL_THRESHOLD_RAD = 0.1  # cells with |alpha| above this take part in the wall count


def _as_arrays(t, alpha, beta):
    t = np.asarray(t, dtype=float)
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    if alpha.ndim == 1:
        alpha = alpha[:, None]
    if beta.ndim == 1:
        beta = beta[:, None]
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be 1-D with at least 2 samples")
    if alpha.shape[0] != t.size or beta.shape != alpha.shape:
        raise ValueError(
            f"shape mismatch: t {t.shape}, alpha {alpha.shape}, beta {beta.shape}; "
            "expected alpha and beta (T, N) with T = len(t)"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(alpha)) and np.all(np.isfinite(beta))):
        raise ValueError("non-finite values in t/alpha/beta (a diverged run?)")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    return t, alpha, beta


def _window(t, settle_window_s):
    span = t[-1] - t[0]
    w = 0.1 * span if settle_window_s is None else float(settle_window_s)
    if not (w >= 0 and math.isfinite(w)):
        raise ValueError(f"settle_window_s={settle_window_s!r} must be finite and >= 0")
    idx = np.nonzero(t >= t[-1] - w)[0]
    if idx.size < 3:
        idx = np.arange(max(0, t.size - 3), t.size)
    return idx


def is_steady(
    t: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    *,
    settle_window_s: float | None = None,
    tol_rad: float = DEFAULT_TOL_RAD,
) -> bool:
    t, alpha, beta = _as_arrays(t, alpha, beta)
    idx = _window(t, settle_window_s)
    ptp = max(np.ptp(alpha[idx], axis=0).max(), np.ptp(beta[idx], axis=0).max())
    return bool(ptp < tol_rad)


def spatial_period(profile: np.ndarray, *, tol_rad: float = DEFAULT_TOL_RAD, n_grid: int = 400) -> float | None:
    """Dominant wavelength (cells) of a 1-D profile sampled at x_j = j - 1/2, or None if flat."""
    u = np.asarray(profile, dtype=float)
    n = u.size
    if n < 3 or np.ptp(u) < tol_rad:
        return None
    x = np.arange(n) + 0.5
    u = u - u.mean()

    def explained(ks: np.ndarray) -> np.ndarray:
        """Share of u's variance fitted by [cos kx, sin kx, 1], for each k in ks, in one batched least-squares
        solve: coef = pinv(B_k) u (rank-deficient at k = pi, where cos kx = 0, as lstsq allows; lstsq's cutoff)."""
        kx = ks[:, None] * x[None, :]
        basis = np.stack([np.cos(kx), np.sin(kx), np.ones_like(kx)], axis=-1)  # (len(ks), n, 3)
        coef = np.linalg.pinv(basis, rcond=np.finfo(float).eps * max(n, 3)) @ u
        resid = u[None, :] - np.einsum("mnj,mj->mn", basis, coef)
        return 1.0 - np.einsum("mn,mn->m", resid, resid) / (u @ u)

    ks = np.linspace(math.pi / n, math.pi, n_grid)
    ev = explained(ks)
    i = int(np.argmax(ev))
    k = ks[i]
    if 0 < i < ks.size - 1:
        r = minimize_scalar(
            lambda kk: -explained(np.array([kk]))[0],
            bounds=(ks[i - 1], ks[i + 1]),
            method="bounded",
            options={"xatol": 1e-9},
        )
        if -r.fun >= ev[i]:
            k = float(r.x)
    return 2 * math.pi / k


def _crossings(t, y, band):
    """Times of zero crossings of y with hysteresis: y must leave [-band, band] on alternate sides."""
    out = []
    side = 0
    last_idx = 0  # index of the last sample outside the band (read only once side != 0)
    for i, v in enumerate(y):
        s = 1 if v > band else (-1 if v < -band else 0)
        if s == 0:
            continue
        if side != 0 and s != side:
            # the sign change happened between last_idx and i: interpolate the zero between them
            j = last_idx
            for k in range(last_idx, i):
                if (y[k] > 0) != (y[k + 1] > 0) or y[k + 1] == 0:
                    j = k
            y0, y1 = y[j], y[j + 1]
            out.append(t[j] + (t[j + 1] - t[j]) * (y0 / (y0 - y1) if y0 != y1 else 0.5))
        side = s
        last_idx = i
    return out


def temporal_period(
    t: np.ndarray,
    alpha: np.ndarray,
    *,
    settle_window_s: float | None = None,
    tol_rad: float = DEFAULT_TOL_RAD,
    until_the_end: bool = False,
) -> float | None:
    """Temporal period (s) of the late motion, or None (see module docstring). until_the_end: None unless the
    last crossing lies in the final window (the motion goes on to the end of the run, not ringing that died)."""
    t = np.asarray(t, dtype=float)
    alpha = np.asarray(alpha, dtype=float)
    if alpha.ndim == 1:
        alpha = alpha[:, None]
    idx = _window(t, settle_window_s)
    ref = np.median(alpha[idx], axis=0)
    dev = alpha - ref
    mag = np.abs(dev).max(axis=1)
    i0 = int(np.argmax(mag))  # peak excursion: free motion follows
    if t.size - i0 < 5:
        return None
    j = int(np.argmax(np.ptp(dev[i0:], axis=0)))
    y = dev[i0:, j]
    band = max(0.5 * tol_rad, 1e-9 * np.abs(y).max())  # one encoder count: quantisation jitter is no oscillation
    cr = _crossings(t[i0:], y, band)
    if len(cr) < 3:
        return None
    if until_the_end and cr[-1] < t[idx[0]]:
        return None
    k = (len(cr) - 1) // 2 * 2  # whole periods only: crossings in the same direction
    return 2.0 * (cr[k] - cr[0]) / k


def growth_rate(t: np.ndarray, alpha: np.ndarray, *, min_amplitude_rad: float = 1e-9) -> float | None:
    """Early exponential growth rate (1/s) of A(t) = max_j |alpha_j(t)|, or None."""
    t = np.asarray(t, dtype=float)
    alpha = np.asarray(alpha, dtype=float)
    if alpha.ndim == 1:
        alpha = alpha[:, None]
    amp = np.abs(alpha).max(axis=1)  # distance from the rest state alpha = 0
    amax = amp.max()
    if not amax > min_amplitude_rad:
        return None
    i_hi = int(np.argmax(amp >= 0.2 * amax))  # first sample at 20 % of the peak
    if i_hi < 4:
        return None
    # the contiguous rise ending at i_hi, restricted to its upper two decades
    i_lo = i_hi
    while i_lo > 0 and amp[i_lo - 1] < amp[i_lo]:
        i_lo -= 1
    while i_lo < i_hi and amp[i_lo] < max(amp[i_hi] * 1e-2, min_amplitude_rad):
        i_lo += 1
    if i_hi - i_lo + 1 < 5 or amp[i_hi] < 3 * amp[i_lo]:
        return None
    tt = t[i_lo : i_hi + 1]
    ly = np.log(amp[i_lo : i_hi + 1])
    slope, icpt = np.polyfit(tt, ly, 1)
    res = ly - (slope * tt + icpt)
    r2 = 1.0 - (res @ res) / max(((ly - ly.mean()) ** 2).sum(), 1e-300)
    if r2 < 0.98 or slope <= 0:
        return None
    return float(slope)


def domain_walls(profile: np.ndarray, *, threshold_rad: float = WALL_THRESHOLD_RAD) -> int:
    """Sign changes of a profile among the cells with |u_j| > threshold_rad (see module docstring)."""
    if not (math.isfinite(threshold_rad) and threshold_rad >= 0):
        raise ValueError(f"threshold_rad={threshold_rad!r} must be finite and >= 0")
    u = np.asarray(profile, dtype=float)
    s = np.sign(u[np.abs(u) > threshold_rad])
    return int(np.count_nonzero(s[1:] != s[:-1]))


def domain_wall_bonds(
    profile: np.ndarray, *, threshold_rad: float = WALL_THRESHOLD_RAD, skip: Sequence[int] = ()
) -> list[float]:
    """Bond positions j + 0.5 of the sign changes counted by domain_walls (cells 1..N; skip: cells left out, as
    design's rest cells), each at the zero of the straight line between the two cells, rounded to the nearest
    bond (see module docstring)."""
    if not (math.isfinite(threshold_rad) and threshold_rad >= 0):
        raise ValueError(f"threshold_rad={threshold_rad!r} must be finite and >= 0")
    u = np.asarray(profile, dtype=float)
    keep = [j for j in range(u.size) if abs(u[j]) > threshold_rad and (j + 1) not in skip]
    out = []
    for a, b in zip(keep[:-1], keep[1:]):
        if np.sign(u[a]) != np.sign(u[b]):
            x = a + (b - a) * u[a] / (u[a] - u[b]) + 1.0  # 1-based position of the zero
            out.append(math.floor(x) + 0.5 if x % 1 else x + 0.5)
    return out


def dominant_mode(profile: np.ndarray) -> int:
    """Index m of the largest orthonormal DCT-II coefficient: free-end chain mode cos(pi m (j - 1/2) / N)."""
    from scipy.fft import dct

    c = dct(np.asarray(profile, dtype=float), type=2, norm="ortho")
    return int(np.argmax(np.abs(c)))


def is_at_rest(
    t: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    *,
    settle_window_s: float | None = None,
    rest_tol_rad: float = REST_TOL_RAD,
) -> bool:
    """Every |alpha_j|, |beta_j| within rest_tol_rad over the final window."""
    t, alpha, beta = _as_arrays(t, alpha, beta)
    idx = _window(t, settle_window_s)
    return bool(max(np.abs(alpha[idx]).max(), np.abs(beta[idx]).max()) <= rest_tol_rad)


def observables(
    t: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    *,
    settle_window_s: float | None = None,
    tol_rad: float = DEFAULT_TOL_RAD,
    wall_threshold_rad: float = WALL_THRESHOLD_RAD,
    rest_tol_rad: float = REST_TOL_RAD,
) -> dict:
    """All observables of a run as a JSON-ready dict (see module docstring for definitions)."""
    if not (math.isfinite(tol_rad) and tol_rad > 0):
        raise ValueError(f"tol_rad={tol_rad!r} must be finite and > 0")
    if not (math.isfinite(rest_tol_rad) and rest_tol_rad > 0):
        raise ValueError(f"rest_tol_rad={rest_tol_rad!r} must be finite and > 0")
    t, alpha, beta = _as_arrays(t, alpha, beta)
    steady = is_steady(t, alpha, beta, settle_window_s=settle_window_s, tol_rad=tol_rad)
    at_rest = is_at_rest(t, alpha, beta, settle_window_s=settle_window_s, rest_tol_rad=rest_tol_rad)
    n = alpha.shape[1]
    walls = 0 if at_rest else domain_walls(alpha[-1], threshold_rad=wall_threshold_rad)
    bonds = [] if at_rest else domain_wall_bonds(alpha[-1], threshold_rad=wall_threshold_rad)
    mode = None if at_rest else dominant_mode(alpha[-1])
    return {
        "steady": steady,
        "at_rest": at_rest,
        "domain_walls": walls,
        "domain_wall_bonds": bonds,
        "pattern_wavelength_cells": (2.0 * (n - 1) / walls) if walls else None,
        "dominant_mode": mode,
        "dominant_mode_lambda_cells": (2.0 * n / mode) if mode else None,
        "pattern_period_cells": None if at_rest else spatial_period(alpha[-1], tol_rad=tol_rad),
        "oscillation_period_s": None
        if steady
        else temporal_period(t, alpha, settle_window_s=settle_window_s, tol_rad=tol_rad, until_the_end=True),
        "amplitude_rad": float(np.abs(alpha[-1]).max()),
        "final_alpha_rad": [float(v) for v in alpha[-1]],
        "final_beta_rad": [float(v) for v in beta[-1]],
        "growth_rate_per_s": growth_rate(t, alpha),
    }
