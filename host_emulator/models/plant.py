"""Fill the compiled plant (he_plant_t) from Params, model options, perturbations and seeded spreads."""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import params as P
from ..params import Params
from ..topology import Topology
from .options import ModelOptions, Perturbation

# he_plant_t -> its scratch buffer: cffi frees the buffer when the plant goes (weak keys)
_keepalive: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class NumericalInstability(RuntimeError):
    """The integration left the finite/physical range; the message names the cause."""

    samples: int | None = None  # output samples completed before the failure, when the solver knows


def spreads(params: Params, options: ModelOptions, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-bond band-stiffness factors (2, nb) and per-cell eta factors (2, n) from the seeded noise options.

    Factor = max(0.2, 1 + s * N(0, 1)) (distribution "normal"), or uniform in [1 - s, 1 + s] ("uniform"). Honey
    (eta_spread) is on the alpha chain only. The open chain of n cells: nb = n, bond j = (j, j + 1) in column j,
    the last column 1 (no bond); any other topology (params.topology, a ring or a sheet of n cells): nb = its
    number of bonds, column b = bond b of Topology.bonds. One draw of (2, bonds) then one of n, from the seed.
    """
    nz = options.noise
    rng = np.random.default_rng(nz.seed)
    topo = plant_topology(params, n)
    nbond = n - 1 if topo is None else topo.nbond
    band = np.ones((2, n if topo is None else nbond))
    eta = np.ones((2, n))
    if nz.band_spread > 0:
        band[:, :nbond] = factors(rng, nz.band_spread, (2, nbond), nz.distribution)
    if nz.eta_spread > 0:
        eta[0] = factors(rng, nz.eta_spread, n, nz.distribution)
    return band, eta


def plant_topology(params: Params, n: int) -> Topology | None:
    """The topology whose bonds the plant gets: None for the open chain (the compiled plant's own chain
    kernels, bonds (j, j + 1)), else params.topology (a ring or a sheet); n must be its number of cells."""
    topo = params.topology
    if topo.is_open_chain:
        return None
    if topo.n != n:
        raise ValueError(f"{topo.describe()}: the plant was asked for {n} cells")
    return topo


def factors(rng: np.random.Generator, s: float, shape, distribution: str = "normal") -> np.ndarray:
    """Spread factors: max(0.2, 1 + s N(0, 1)) ("normal") or uniform in [1 - s, 1 + s] (at least 0.2)."""
    if distribution == "uniform":
        return np.maximum(0.2, 1 + s * rng.uniform(-1.0, 1.0, shape))
    return np.maximum(0.2, 1 + s * rng.standard_normal(shape))


def draw_rig(params: Params, perturbations: Sequence[Perturbation], options: ModelOptions | None):
    """(params, perturbations) with the noise options' inertia, push and timing draws applied (NoiseOptions): one
    inertia factor per chain, one torque factor and one start shift per perturbation. Their own stream
    (default_rng([seed, 1])), so the band and viscosity draws of a seed stay what they were; with every one of these
    spreads 0 the arguments come back as they are."""
    if options is None:
        return params, perturbations
    nz = options.noise
    if not (nz.inertia_spread > 0 or nz.push_spread > 0 or nz.push_timing_s > 0):
        return params, perturbations
    rng = np.random.default_rng([nz.seed, 1])
    if nz.inertia_spread > 0:
        fi = factors(rng, nz.inertia_spread, 2, nz.distribution)
        params = params.with_overrides(I_a=params.I_a * float(fi[0]), I_b=params.I_b * float(fi[1]))
    m = len(perturbations)
    ft = factors(rng, nz.push_spread, m, nz.distribution) if nz.push_spread > 0 else np.ones(m)
    if nz.push_timing_s > 0:
        u = rng.uniform(-1.0, 1.0, m) if nz.distribution == "uniform" else rng.standard_normal(m)
        dt = nz.push_timing_s * u
    else:
        dt = np.zeros(m)
    out = [
        dataclasses.replace(q, torque_Nm=q.torque_Nm * float(f), start_s=max(0.0, q.start_s + float(d)))
        for q, f, d in zip(perturbations, ft, dt)
    ]
    return params, out


def build_plant(
    ffi: Any,
    lib: Any,
    params: Params,
    options: ModelOptions,
    n: int,
    perturbations: Sequence[Perturbation],
    *,
    ideal_reaction: bool,
) -> Any:  # cffi FFI/lib in, the he_plant_t cdata out
    """A new he_plant_t (cffi owned) for n cells, the bonds of params.topology (the open chain: bonds NULL, its own
    compiled kernels). Raises ValueError if the C side rejects it."""
    if not 1 <= n <= lib.HE_MAX_CELLS:
        raise ValueError(f"cells = {n}: must be in 1..{lib.HE_MAX_CELLS}")
    if len(perturbations) > lib.HE_MAX_PERT:
        raise ValueError(f"{len(perturbations)} perturbations: at most {lib.HE_MAX_PERT}")
    p = ffi.new("he_plant_t *")
    p.n = n
    p.inertia = 1 if options.inertia else 0
    p.bands = lib.HE_BANDS_CUBIC if options.bands == "cubic" else lib.HE_BANDS_LINEAR
    p.beta_geometry = lib.HE_BETA_GEOMETRIC if options.beta_geometry == "geometric" else lib.HE_BETA_SMALL
    p.reaction = lib.HE_REACT_IDEAL if ideal_reaction else lib.HE_REACT_NONE
    p.slack_f0 = 1 if params.slack_f0 else 0
    p.I = [params.I_a, params.I_b]
    p.k_lin = [params.ka_eff, params.kb_eff]  # linear bands: the cubic law's small-deflection slope
    p.band_scale = params.band_scale
    p.lever = [P.R_ALPHA_M, P.R_BETA_ARM_M]
    p.lattice_m = P.LATTICE_M
    p.delta0 = [P.DELTA_A0_M, P.DELTA_B0_M]
    p.delta_max = [0.3 * P.L_ALPHA_M, 0.3 * P.L_BETA_M]
    p.coef = [list(P.BAND_A_COEF), list(P.BAND_B_COEF)]
    if params.per_cell_keys:
        # one law per cell (he_plant.h react_cell): rows k_ab, sigma, k1, k2, alpha* of n doubles each; the
        # scalars hold cell 1's values (what code reading only them sees)
        rows = np.concatenate([params.per_cell(k) for k in P.REACTION_KEYS])
        if rows.size != lib.HE_RC_COUNT * n:
            raise ValueError(f"per-cell reaction parameters: {rows.size} values for {n} cells")
        rc = ffi.new("double[]", rows.tolist())
        p.react_cell = rc
        first = params.cell(1)
        p.k_ab, p.sigma, p.k1, p.k2, p.astar = first.k_ab, first.sigma, first.k1, first.k2, first.alpha_star
    else:
        rc = ffi.NULL
        p.k_ab, p.sigma, p.k1, p.k2, p.astar = params.k_ab, params.sigma, params.k1, params.k2, params.alpha_star
    p.speed_const = params.speed_const
    p.react_limit = params.torque_limit_nm  # inf: no actuator limit
    band, eta = spreads(params, options, n)
    topo = plant_topology(params, n)
    nb = band.shape[1]
    # the per-cylinder rows eta, mgain, volt (n each) and the per-bond kscale rows (nb each), one owned block
    arrays = np.zeros(6 * n + 2 * nb)
    arrays[:n] = params.eta_alpha * eta[0]
    arrays[n : 2 * n] = params.eta_beta * eta[1]
    arrays[6 * n :] = band.ravel()
    mem = ffi.new("double[]", len(arrays))
    ffi.memmove(mem, ffi.from_buffer("double[]", arrays), arrays.nbytes)
    p.eta = [mem, mem + n]
    p.mgain = [mem + 2 * n, mem + 3 * n]
    p.volt = [mem + 4 * n, mem + 5 * n]
    p.kscale = [mem + 6 * n, mem + 6 * n + nb]
    if topo is None:
        bonds = ffi.NULL  # the open chain: bonds (j, j + 1), the compiled chain kernels
        p.nbond = 0
    else:
        pairs = np.ascontiguousarray(topo.bonds, dtype=np.int32)
        bonds = ffi.new("int32_t[]", max(1, pairs.size))
        ffi.memmove(bonds, ffi.from_buffer("int32_t[]", pairs), pairs.nbytes)
        p.nbond = len(pairs)
    p.bonds = bonds
    p.npert = len(perturbations)
    for i, q in enumerate(perturbations):
        e = p.pert[i]
        e.cell = q.cell - 1
        e.chain = 0 if q.chain == "alpha" else 1
        e.torque = q.torque_Nm
        e.t0 = q.start_s
        e.t1 = q.start_s + q.duration_s
    # the steppers' scratch, allocated once per plant (he_step.h HE_WORK_PER_STATE); kept alive by the plant
    work = ffi.new("double[]", lib.HE_WORK_PER_STATE * 2 * n)
    p.work = work
    p.work_len = lib.HE_WORK_PER_STATE * 2 * n
    _keepalive[p] = (work, rc, mem, bonds)
    if lib.he_plant_check(p) != lib.HE_OK:
        raise ValueError(
            "plant parameters rejected (non-positive inertia/damping or non-finite value); "
            f"check I_a={params.I_a}, I_b={params.I_b}, eta_a={params.eta_a}, gamma={params.gamma}, "
            f"eta_scale={params.eta_scale}"
        )
    return p


def step_limit(ffi: Any, lib: Any, plant: Any, stepper: int) -> tuple[float, str]:
    """(largest stable step in s, which chain limits it)."""
    ch = ffi.new("int *")
    h = lib.he_step_limit(plant, stepper, ch)
    return float(h), ("alpha", "beta", "none")[ch[0]] if ch[0] >= 0 else "none"


def error_text(lib: Any, rc: int) -> str:
    return {
        lib.HE_ERR_NONFINITE: "state became NaN/inf",
        lib.HE_ERR_DIVERGED: f"state diverged (|angle| > {lib.HE_ANGLE_LIMIT_RAD} rad or "
        f"|speed| > {lib.HE_SPEED_LIMIT_RAD_S} rad/s)",
        lib.HE_ERR_BAND: (
            f"a band stretched beyond {lib.HE_BAND_STOP_FACTOR}x the cubic fit's range "
            "(30% strain): the motion grew out of the physical range"
        ),
        lib.HE_ERR_ARG: "invalid plant configuration",
        lib.HE_ERR_STEPPER: "unknown stepper id",
        lib.HE_ERR_NOMEM: "out of memory for the run's scratch arrays",
        lib.HE_ERR_SOLVE: (
            "the IMEX stepper's sparse solve (conjugate gradients on the bonds) did not converge: the implicit "
            "matrix lost its positive definiteness (a band law with a negative slope) or the step is far too large"
        ),
        lib.HE_ERR_TOL: (
            "the adaptive step control needed a step below its smallest step (1e-12 s): the error tolerance "
            "cannot be met there (a discontinuity or a stiff stretch); loosen model_options.tol"
        ),
    }.get(rc, f"error {rc}")


def choose_step(
    limit: float, span: float, dt_max: float | None, stepper: str, chain: str, what: str = "model_options.dt"
) -> tuple[float, int]:
    """Split `span` (s) into m equal steps h <= dt_max (or <= limit/4 when dt_max is None).

    A requested dt above the stable limit is refused with an error naming the limit."""
    if dt_max is not None and dt_max > limit:
        raise ValueError(
            f"{what} = {dt_max:g} s exceeds the stable step limit {limit:.4g} s of stepper "
            f"{stepper!r} (stiffest mode on the {chain} chain: inertia/stiffness/damping); "
            f"use dt <= {limit:.4g}"
        )
    target = dt_max if dt_max is not None else limit / 4
    m = max(1, int(np.ceil(span / target - 1e-9)))
    return span / m, m
