"""Physical constants of the rig (docs/physics.md) and the explicit choices where the source is silent.

Everything is SI (N*m, rad, s, V) unless a name says otherwise. A `Params`
instance is immutable; use ``dataclasses.replace`` or ``Params.with_overrides``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from metacell_common.reaction import REACTION_DEFAULTS, REACTION_KEYS
from protocol import definition as _wire_units

from .topology import Topology, TopologyError

FloatArray = float | np.ndarray  # a number, or a numpy array of them elementwise
PerCell = float | tuple[float, ...]  # one value for every cell, or one value per cell (cell 1 first)

# The reaction law's parameters (docs/physics.md#reaction-torques): each may be one value or one per cell (the
# cells' firmware registers K_AB, SIGMA, K1, K2, ASTAR are set one cell at a time). REACTION_KEYS, their defaults
# and SIGMA_MAIN are metacell_common.reaction's (the command tool's `apply` uses them too).

# ---- measured constants (docs/physics.md#constants, #band-torque) -------------------------------------
LATTICE_M = 0.060  # a, lattice parameter
R_ALPHA_M = 0.010  # r, alpha cylinder radius (alpha bands at r)
R_BETA_ARM_M = 0.020  # 2r, beta band attachment radius
I_ALPHA = 6.39e-7  # kg m^2
I_BETA = 3.13e-7  # kg m^2
ETA_ALPHA = 4.18e-4  # N m s (honey, measured)
K_ALPHA_TABLE = 1.46e-2  # N m / rad, linearised band stiffness (table)
K_BETA_TABLE = 4.57e-2  # N m / rad
L_ALPHA_M = 0.083  # band rest lengths
L_BETA_M = 0.055
DELTA_A0_M = LATTICE_M + R_ALPHA_M * math.pi - L_ALPHA_M  # 8.4 mm pre-stretch
DELTA_B0_M = LATTICE_M - L_BETA_M  # 5 mm

# cubic band force fits f(delta) [N], delta in metres: c0 + c1 d + c2 d^2 + c3 d^3
BAND_A_COEF = (0.28, 268.08, -8817.84, 123843.17)
BAND_B_COEF = (0.19, 164.96, -5965.25, 118186.51)

# ---- motor and driver (docs/physics.md#actuators) ----------------------------------------------
MOTOR_KT_NM_PER_V = 0.09 / 12.0  # stall torque / rated voltage
MOTOR_SPEED_CONST = 49.8  # S_L, rad/(V s), measured (datasheet 47.9)
SUPPLY_V = 9.0
VMAX_V = 5.86  # DRV8874 2.1 A limit at 9 V
COUNTS_PER_REV = _wire_units.COUNTS_PER_REV  # the wire definition (protocol/definition.py); C: MC_COUNTS_PER_REV

# ---- reaction law (docs/physics.md#reaction-torques) -------------------------------------------------
SIGMA_REGIMES = {"conditional": 9 / 125, "unconditional": 6 / 125, "stable": 14 / 125}


# the band law and the reaction law are written once, in physics.py (re-exported here for old callers)
from .physics import band_force, band_slope, psi_prime  # noqa: E402,F401


@dataclass(frozen=True)
class Params:
    """Parameters of one lattice. Defaults are the source's experiment values.

    Explicit choices where the source is silent or inconsistent:

    * ``gamma`` = eta_b / eta_a. Not measured; the source assumes 0.1 "for
      numerical stability". Default 0.1.
    * ``band_scale``: the piecewise band formulas (both bands of a pair pull)
      have a small-deflection slope of 2 r^2 f'(delta0) (alpha) and
      8 r^2 f'(delta0) (beta), twice the tabulated k = r^2 f' (k_a, k_b here).
      The torque of the non-linear band law is multiplied by ``band_scale``,
      and every linear model (linear bands, the continuum model, the
      dispersion relation) uses the same effective stiffness
      ``ka_eff = 2 * band_scale * k_a`` (likewise ``kb_eff``). Default 1.0:
      the physical pair of bands, the formula as printed, which is what the
      rig and the source's own simulations and experiments show (patterns of
      15, 10, 7.5 and 15 cells). 0.5 is the table-k reading, under which the
      dispersion relation reproduces the source's linear-stability figure
      (docs/band-stiffness.md).
    * ``actuator_limit``: the lattice model's ideal reaction torque is
      clipped to +-kt*vmax_v (the 5.86 V cap: about 44 mN m), as the firmware
      and the drivers do on the rig. Default True. Without it, sigma = 14/125
      with inertia grows without bound (the uniform mode is unstable); with it
      the motion is a bounded limit cycle. The continuum model ignores it.
    * ``slack_f0``: a slack band contributes f(0) != 0 in the source's formula.
      True (default) keeps that literal reading; False makes a slack band push 0.
    * ``eta_scale`` multiplies both eta_a and eta_b (scene 4 uses 10).
    * ``bemf_comp``: firmware back-EMF compensation (15/16 of omega/S_L, from a
      low-lag velocity observer). Default False, as in the source build and the
      firmware's own default; uncompensated, each motor adds Kt/S_L = 1.5e-4 N m s.
      On, sigma = 14/125 oscillates at the lattice's 0.03 s period and 9/125 keeps
      its patterns (docs/emulator.md); the real rig should use it on.
    """

    cells: int = 16
    # topology (host_emulator/topology.py): shape () is a chain of `cells`; (rows, cols) a sheet of rows*cols cells
    shape: tuple[int, ...] = ()
    lattice: str = "chain"  # "chain" | "square" | "hex"
    boundary: str = "open"  # "open" | "periodic" (a ring, or a sheet wrapped both ways)
    # reaction law, N m / rad (alpha_star in rad): one value, or a tuple of one value per cell (REACTION_KEYS)
    k_ab: PerCell = REACTION_DEFAULTS["k_ab"]
    k1: PerCell = REACTION_DEFAULTS["k1"]
    k2: PerCell = REACTION_DEFAULTS["k2"]
    alpha_star: PerCell = REACTION_DEFAULTS["alpha_star"]
    sigma: PerCell = REACTION_DEFAULTS["sigma"]
    # mechanics
    I_a: float = I_ALPHA
    I_b: float = I_BETA
    eta_a: float = ETA_ALPHA
    gamma: float = 0.1
    eta_scale: float = 1.0
    k_a: float = K_ALPHA_TABLE
    k_b: float = K_BETA_TABLE
    band_scale: float = 1.0
    slack_f0: bool = True
    # motor / driver / control
    supply_v: float = SUPPLY_V
    vmax_v: float = VMAX_V
    kt: float = MOTOR_KT_NM_PER_V
    speed_const: float = MOTOR_SPEED_CONST
    control_rate_hz: float = 2000.0
    pwm_top: int = 2400
    bemf_comp: bool = False
    actuator_limit: bool = True

    @property
    def topology(self) -> Topology:
        """The lattice these parameters describe (cells and bonds); TopologyError when shape and cells disagree."""
        return _topology(self.cells, self.shape, self.lattice, self.boundary)

    @property
    def eta_alpha(self) -> float:
        return self.eta_a * self.eta_scale

    @property
    def eta_beta(self) -> float:
        return self.eta_a * self.gamma * self.eta_scale

    @property
    def ka_eff(self) -> float:
        """Linearised alpha band stiffness of the simulated band law, N m/rad: 2 * band_scale * k_a."""
        return 2.0 * self.band_scale * self.k_a

    @property
    def kb_eff(self) -> float:
        """Linearised beta band stiffness of the simulated band law, N m/rad: 2 * band_scale * k_b."""
        return 2.0 * self.band_scale * self.k_b

    @property
    def torque_limit_nm(self) -> float:
        """Largest motor torque the drivers can apply (kt * vmax_v), N m; inf when actuator_limit is off."""
        return self.kt * self.vmax_v if self.actuator_limit else math.inf

    @property
    def d(self) -> float:
        """Stiffness ratio k_b / k_a (about 3.12)."""
        return self.k_b / self.k_a

    @property
    def eta_bemf(self) -> float:
        """Extra viscous coefficient of an uncompensated motor: Kt / S_L."""
        return self.kt / self.speed_const

    # ---- per-cell reaction parameters ---------------------------------------------------------------
    def per_cell(self, name: str) -> np.ndarray:
        """The reaction parameter `name` of every cell, shape (cells,) (a scalar repeated for every cell)."""
        if name not in REACTION_KEYS:
            raise KeyError(f"{name!r} is not a reaction parameter ({', '.join(REACTION_KEYS)})")
        v = getattr(self, name)
        if isinstance(v, tuple):
            if len(v) != self.cells:
                raise ValueError(f"params.{name}: {len(v)} values for {self.cells} cells")
            return np.array(v, dtype=float)
        return np.full(self.cells, float(v))

    @property
    def per_cell_keys(self) -> tuple[str, ...]:
        """The reaction parameters given one value per cell (a tuple), whether or not the values differ."""
        return tuple(k for k in REACTION_KEYS if isinstance(getattr(self, k), tuple))

    @property
    def varying_keys(self) -> tuple[str, ...]:
        """The reaction parameters whose per-cell values differ between cells (empty: a uniform chain)."""
        return tuple(k for k in self.per_cell_keys if len(set(getattr(self, k))) > 1)

    @property
    def heterogeneous(self) -> bool:
        """True when some reaction parameter differs between cells."""
        return bool(self.varying_keys)

    def value(self, name: str) -> float:
        """The one value of reaction parameter `name` shared by every cell; ValueError naming the key when the
        cells' values differ (a scalar-only consumer, e.g. the dispersion relation of a uniform chain)."""
        v = getattr(self, name)
        if not isinstance(v, tuple):
            return float(v)
        if len(set(v)) > 1:
            raise ValueError(
                f"params.{name} differs between cells ({min(v):g} .. {max(v):g}): this needs one value for every "
                "cell (the chain's own linear theory is analysis.chain)"
            )
        return float(v[0])

    def uniform(self) -> Params:
        """These parameters with every per-cell tuple whose values agree made a scalar; ValueError (naming the key)
        when some reaction parameter differs between cells."""
        kw: dict[str, Any] = {k: self.value(k) for k in self.per_cell_keys}
        return dataclasses.replace(self, **kw) if kw else self

    def cell(self, j: int) -> Params:
        """The scalar parameters of cell j (1-based): every per-cell tuple replaced by cell j's value."""
        if not 1 <= j <= self.cells:
            raise IndexError(f"cell {j} outside 1..{self.cells}")
        kw: dict[str, Any] = {k: float(getattr(self, k)[j - 1]) for k in self.per_cell_keys}
        return dataclasses.replace(self, **kw) if kw else self

    def with_overrides(self, **kw: Any) -> Params:
        names = {f.name for f in dataclasses.fields(self)}
        bad = sorted(set(kw) - names)
        if bad:
            raise KeyError(f"unknown parameter(s): {', '.join(bad)}; known: {', '.join(sorted(names))}")
        return dataclasses.replace(self, **kw)

    def psi_prime(self, alpha):
        """Tri-linear psi'(alpha) of docs/physics.md#reaction-torques (float or numpy array): physics.psi_prime."""
        return psi_prime(self, alpha)


@functools.lru_cache(maxsize=64)
def _topology(cells: int, shape: tuple[int, ...], lattice: str, boundary: str) -> Topology:
    spec = list(shape) if shape else cells
    t = Topology.from_spec(spec, None if lattice == "chain" and not shape else lattice, boundary)
    if t.n != cells:
        raise TopologyError(f"cells = {cells} but shape {list(shape)} holds {t.n}")
    return t
