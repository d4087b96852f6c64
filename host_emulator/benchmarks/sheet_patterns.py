"""Stripes or spots (docs/sheets.md#stripes-or-spots): the lattice's own law on a periodic sheet from small noise,
overdamped, integrated in numpy; prints what pattern forms and how symmetric it is between alpha > 0 and alpha < 0.

    python -m host_emulator.benchmarks.sheet_patterns --sigma 9/125 --size 32 [--lattice hex] [--bias 0.002]

The right-hand side is the lattice model's (docs/physics.md): the reaction law of physics.reaction with the
actuator limit, the cubic band law with its slack rule (models.reference's bond torque, small-angle beta), on the
bonds of Topology((size, size), lattice, periodic). Inertia is left out (the stationary patterns are the zeros of
the same forces; only the approach differs). Its linear part is integrated exactly in Fourier space (every plane
wave's 2x2 exponential: the stiff band diffusion costs nothing), the rest explicitly (exponential Euler, step
--dt). --bias adds a constant torque h (N m) to every R_a: the one term that is even in the angles (it breaks
alpha -> -alpha), which the model does not have; it is here to show what such a term does. --compiled runs the
compiled lattice model instead (models.lattice, with inertia) and adds analysis.pattern2d's reading.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from ..models.options import ModelOptions
from ..models.reference import ReferencePlant
from ..params import Params
from ..physics import reaction, reaction_jacobian
from ..topology import Topology


def _phi(m: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """exp(M h) and h phi1(M h) = M^-1 (exp(M h) - 1) for a stack of 2x2 matrices, via the augmented 4x4."""
    from scipy.linalg import expm

    aug = np.zeros((*m.shape[:-2], 4, 4))
    aug[..., :2, :2] = m * h
    aug[..., :2, 2:] = np.eye(2) * h
    e = expm(aug)
    return e[..., :2, :2], e[..., :2, 2:]


def simulate(
    p: Params, size: int, lattice: str, t_end: float, dt: float, seed: int, bias: float = 0.0, bands: str = "cubic"
) -> np.ndarray:
    """alpha at t_end (size, size), from alpha, beta ~ N(0, 1e-3) rad."""
    topo = Topology((size, size), lattice, True)
    n = topo.n
    plant = ReferencePlant(p.with_overrides(cells=2), ModelOptions(bands=bands))
    b = topo.bonds
    jr = reaction_jacobian(p)
    kd = np.array([p.ka_eff, p.kb_eff])
    eta = np.array([p.eta_alpha, p.eta_beta])
    ph = 2 * math.pi * np.fft.fftfreq(size)
    q = topo.symbol(ph[None, :], ph[:, None])  # (rows, cols): phase per column, per row
    m = np.broadcast_to(jr, (*q.shape, 2, 2)).copy()
    m[..., 0, 0] -= q * kd[0]
    m[..., 1, 1] -= q * kd[1]
    m /= eta[:, None]
    ex, ph1 = _phi(m, dt)
    lim = p.torque_limit_nm

    def nonlinear(x: np.ndarray) -> np.ndarray:
        """Every force but the linear part's (N m), (2, n)."""
        a, be = x
        ra, rb = reaction(p, a, be)
        out = np.stack([np.clip(ra + bias, -lim, lim), np.clip(rb, -lim, lim)]) - np.einsum("ij,jn->in", jr, x)
        for ch in range(2):
            xs, xo = x[ch, b[:, 0]], x[ch, b[:, 1]]
            tau = plant.bond_torque(ch, xs, xo) - kd[ch] * (xs - xo)  # the band law beyond its slope
            np.add.at(out[ch], b[:, 0], -tau)
            np.add.at(out[ch], b[:, 1], tau)
        return out

    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1e-3, (2, n))
    for _ in range(int(round(t_end / dt))):
        nl = nonlinear(x) / eta[:, None]
        xh = np.fft.fft2(x.reshape(2, size, size))
        nh = np.fft.fft2(nl.reshape(2, size, size))
        xh = np.einsum("rcij,jrc->irc", ex, xh) + np.einsum("rcij,jrc->irc", ph1, nh)
        x = np.fft.ifft2(xh).real.reshape(2, n)
    return x[0].reshape(size, size)


def simulate_compiled(
    p: Params, size: int, lattice: str, t_end: float, seed: int, dt_out: float = 0.05
) -> tuple[np.ndarray, np.ndarray, Topology]:
    """The compiled lattice model itself (models.lattice: inertia, its default stepper, the cubic band law, the
    actuator limit) on the periodic sheet from the same noise; (t, alpha (samples, n), topology)."""
    from ..models.lattice import LatticeModel

    topo = Topology((size, size), lattice, True)
    q = p.with_overrides(cells=topo.n, shape=topo.shape, lattice=lattice, boundary="periodic")
    rng = np.random.default_rng(seed)
    s = LatticeModel(q, [], ModelOptions(dt_out=dt_out)).solver(x0=rng.normal(0.0, 1e-3, 2 * topo.n))
    t, a, _ = s.advance_many(int(round(t_end / dt_out)))
    return t, a, topo


def _regions(mask: np.ndarray) -> list[int]:
    """Areas (cells) of the connected regions of a boolean grid, periodic (regions meeting across an edge merged)."""
    from scipy import ndimage

    lab, k = ndimage.label(mask)
    parent = list(range(k + 1))

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, c in list(zip(lab[0], lab[-1])) + list(zip(lab[:, 0], lab[:, -1])):
        if a and c:
            parent[find(int(a))] = find(int(c))
    area: dict[int, int] = {}
    for i, cnt in zip(*np.unique(lab[lab > 0], return_counts=True)):
        area[find(int(i))] = area.get(find(int(i)), 0) + int(cnt)
    return sorted(area.values())


def describe(alpha: np.ndarray, lattice: str) -> dict:
    """What the pattern is: its dominant wavelength lambda (the spectrum's peak), the share of cells with
    alpha > 0, the connected regions of each sign (periodic) and the mean coherence of the gradient's structure
    tensor over half a wavelength (1: locally one direction; 0: isotropic).

    reading: a sign whose regions are all compact (each smaller than lambda^2 cells) and at least three forms
    spots; "spots of alpha < 0" (or > 0) when one sign does, "checkerboard" when both do, else "stripes" (a
    labyrinth of them from noise: every region of both signs extended)."""
    from scipy import ndimage

    size = alpha.shape[0]
    ph = 2 * math.pi * np.fft.fftfreq(size)
    spec = np.abs(np.fft.fft2(alpha - alpha.mean())) ** 2
    spec[0, 0] = 0.0
    r, c = np.unravel_index(int(np.argmax(spec)), spec.shape)
    k_col = ph[c]
    k_row = (ph[r] - 0.5 * ph[c]) * 2 / math.sqrt(3) if lattice == "hex" else ph[r]
    lam = 2 * math.pi / math.hypot(k_row, k_col)
    d_col = 0.5 * (np.roll(alpha, -1, 1) - np.roll(alpha, 1, 1))
    d_row = 0.5 * (np.roll(alpha, -1, 0) - np.roll(alpha, 1, 0))
    gx, gy = d_col, ((d_row - 0.5 * d_col) * 2 / math.sqrt(3) if lattice == "hex" else d_row)
    jxx, jyy, jxy = (ndimage.gaussian_filter(z, lam / 2, mode="wrap") for z in (gx * gx, gy * gy, gx * gy))
    coh = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2) / np.maximum(jxx + jyy, 1e-300)
    cell_area = math.sqrt(3) / 2 if lattice == "hex" else 1.0
    pos, neg = _regions(alpha > 0), _regions(alpha < 0)

    def spots(areas: list[int]) -> bool:
        return len(areas) >= 3 and max(areas) * cell_area < lam * lam

    sp, sn = spots(pos), spots(neg)
    reading = "checkerboard" if sp and sn else "spots of alpha > 0" if sp else "spots of alpha < 0" if sn else "stripes"
    return {
        "max_abs_alpha_rad": float(np.abs(alpha).max()),
        "mean_alpha_rad": float(alpha.mean()),
        "share_positive": float((alpha > 0).mean()),
        "wavelength_cells": lam,
        "regions_positive": len(pos),
        "regions_negative": len(neg),
        "largest_region_cells": [max(pos, default=0), max(neg, default=0)],
        "coherence": float(coh.mean()),
        "reading": reading,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.sheet_patterns",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--sigma", default="9/125")
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--lattice", choices=("square", "hex"), default="square")
    ap.add_argument("--t-end", type=float, default=3.0)
    ap.add_argument("--dt", type=float, default=1e-4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bias", type=float, default=0.0, help="constant torque added to R_a, N m (not in the model)")
    ap.add_argument("--bands", choices=("cubic", "linear"), default="cubic")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a Params field")
    ap.add_argument(
        "--compiled",
        action="store_true",
        help="run the compiled lattice model instead (inertia, its own stepper; no --bias, --bands, --dt) and add "
        "analysis.pattern2d's reading",
    )
    ap.add_argument("--png", default=None, help="also draw alpha at t_end to this PNG")
    ap.add_argument("--npz", default=None, help="also save alpha at t_end (rows, cols) to this .npz")
    args = ap.parse_args(argv)
    from ..analysis.cli import _number, parse_set

    p = parse_set(Params(sigma=_number(args.sigma, "--sigma")), args.set)
    t0 = time.perf_counter()
    if args.compiled:
        from ..analysis.pattern2d import measures

        t, a, topo = simulate_compiled(p, args.size, args.lattice, args.t_end, args.seed)
        alpha = topo.grid(a[-1])
        d = describe(alpha, args.lattice)
        m = measures(t, a, topo)
        d["pattern2d"] = {k: m[k] for k in ("pattern_kind", "dominant_wavelength_cells")}
        args.bias, args.bands = 0.0, "cubic (compiled lattice model, inertia)"
    else:
        alpha = simulate(p, args.size, args.lattice, args.t_end, args.dt, args.seed, args.bias, args.bands)
        d = describe(alpha, args.lattice)
    print(
        f"{args.size} x {args.size} periodic {args.lattice}, sigma = {p.sigma:.4g}, bias = {args.bias:g} N m, "
        f"bands {args.bands}, t = {args.t_end:g} s, seed {args.seed}"
        + (f", {' '.join(args.set)}" if args.set else "")
        + f" ({time.perf_counter() - t0:.0f} s)"
    )
    for k, v in d.items():
        print(f"  {k:<22} {v}")
    if args.npz:
        np.savez_compressed(args.npz, alpha=alpha)
    if args.png:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(4, 4))
        ax = fig.add_subplot(111)
        lim = float(np.abs(alpha).max()) or 1.0
        if args.lattice == "hex":
            xy = Topology(alpha.shape, "hex", True).positions()
            ax.scatter(xy[:, 0], xy[:, 1], c=alpha.ravel(), cmap="RdBu_r", vmin=-lim, vmax=lim, s=12, marker="h")
            ax.invert_yaxis()
            ax.set_aspect("equal")
        else:
            ax.imshow(alpha, cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_title(f"alpha at {args.t_end:g} s: {d['reading']}", fontsize=8)
        fig.savefig(args.png, dpi=100)
    return 0


if __name__ == "__main__":
    sys.exit(main())
