"""Model switches of a scene ([model_options]) and perturbations, validated with errors that name the key."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from typing import Any

from .steppers import DEFAULT_STEPPER, STEPPERS

CHAINS = ("alpha", "beta")


class ConfigError(ValueError):
    """A scene or option value is invalid; the message names the key."""


@dataclass(frozen=True)
class NoiseOptions:
    """Seeded noise: the ways a rig differs from the model (docs/physics.md#the-rigs-uncertainty). Each spread s
    draws a factor per bond, cell, chain or push: 1 + s*N(0,1) (clipped at 0.2) with distribution "normal", uniform
    in [1 - s, 1 + s] with "uniform"; push_timing_s shifts each push's start by t*N(0,1) or uniformly in [-t, t].
    Encoder noise is hil only (the image tier refuses it). Every spread 0 (the default): the scene's own values,
    nothing drawn."""

    seed: int = 0
    band_spread: float = 0.0  # stiffness factor of each band pair (bond), both chains
    eta_spread: float = 0.0  # honey viscosity factor of each cell (alpha chain)
    encoder_jitter_counts: float = 0.0  # std dev of the sampled encoder position, counts
    encoder_glitch_prob: float = 0.0  # per encoder per plant step: an illegal AB pair
    inertia_spread: float = 0.0  # inertia factor of each chain (the plant holds one inertia per chain)
    push_spread: float = 0.0  # torque factor of each perturbation (a hand's push)
    push_timing_s: float = 0.0  # shift of each perturbation's start, s (a start below 0 becomes 0)
    distribution: str = "normal"  # "normal" or "uniform": how the factors and shifts above are drawn


@dataclass(frozen=True)
class ImageOptions:
    """The image model's switches ([model_options.image]). None of them changes a result but cycle_model and boot
    (and fast_forward_timed for an image whose polling loop branches on the time otherwise than monotonically)."""

    threads: int = 1  # threads the boards run on (cells that cannot affect anyone run at the same time)
    cycle_model: str = "cache"  # "cache": flash waits on NVM cache misses; "worst": a wait on every fetch
    fast_forward: bool = True  # skip loop() passes proven idle (results unchanged; a test compares)
    # also skip the passes of a loop that polls the time (the primary's wait on its I2C bus), each skip after a probe
    # of a later pass; exact when its branches are monotone in the time read, as deadlines and elapsed-time checks
    # are (image/csrc/sam_ff.c; docs/image-tier.md, "Passes that read the time"): off for an image whose polling
    # loop branches on a bit of the time
    fast_forward_timed: bool = True
    round_s: float = 0.0  # longest time the boards run apart before the world meets them (0: the plant window)
    # "direct" (the application starts at once) or "bootloader" (the XIAO's UF2 bootloader, found through
    # MC_BOOTLOADER, runs first and starts it: power-on +6.9 ms, other resets +0.9 s; image/bootloader.py)
    boot: str = "direct"
    # what the motors see of TCC0's PWM: "mean" (CC / (PER + 1) over each window) or "waveform" (the output's own
    # edges: the counter's phase, prescaler and period); motor_inductance (waveform only): the motors' electrical
    # time constant L / R in the plant (image/world.py MOTOR_L_H, MOTOR_R_OHM; docs/image-tier.md)
    pwm: str = "mean"
    motor_inductance: bool = False


IMAGE_THREADS_MAX = 16
IMAGE_ROUND_MIN_S = 1e-6  # round_s below this (48 CPU cycles) only multiplies the rounds' cost (limits.image_cost)
CYCLE_MODELS = ("cache", "worst")
BOOT_MODES = ("direct", "bootloader")  # image/bootloader.py BOOT_MODES
PWM_PATHS = ("mean", "waveform")  # image/world.py PWM_PATHS


@dataclass(frozen=True)
class ModelOptions:
    """[model_options] of a scene. Defaults: the physics the source's own simulations use."""

    inertia: bool = True
    bands: str = "cubic"  # "cubic" (docs/physics.md#band-torque fit, slack, x band_scale) | "linear" (table k)
    beta_geometry: str = "small"  # "small" | "geometric" (docs/physics.md#band-torque full form)
    stepper: str = DEFAULT_STEPPER
    dt: float | None = None  # largest plant step, s (None: a quarter of the stable limit; adaptive steppers: no cap)
    tol: float | None = None  # adaptive steppers (dop853, lattice): error tolerance per step (None: DEFAULT_TOL)
    dt_out: float = 0.01  # output sample interval, s
    perturb_via: str = "plant"  # hil: "plant" (external torque, like a hand) | "firmware" (mc_cell_perturb)
    substeps: int | None = None  # hil: plant steps per control tick (None: from dt / stable limit)
    points_per_cell: int = 4  # continuum grid
    noise: NoiseOptions = field(default_factory=NoiseOptions)
    image: ImageOptions = field(default_factory=ImageOptions)


DEFAULT_TOL = 1e-6  # tol when an adaptive stepper runs without one (about 5e-9 rad on the 16-cell lattice scene)
TOL_RANGE = (1e-13, 1e-1)  # tighter than 1e-13 is below double rounding for these states; looser is not a tolerance

_CHOICES = {
    "bands": ("cubic", "linear"),
    "beta_geometry": ("small", "geometric"),
    "perturb_via": ("plant", "firmware"),
}


def _num(key, v, *, integer=False, positive=False, nonneg=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(f"{key} = {v!r}: expected a number")
    if integer and (not float(v).is_integer()):
        raise ConfigError(f"{key} = {v!r}: expected an integer")
    if not math.isfinite(v):
        raise ConfigError(f"{key} = {v!r}: must be finite")
    if positive and not v > 0:
        raise ConfigError(f"{key} = {v!r}: must be > 0")
    if nonneg and v < 0:
        raise ConfigError(f"{key} = {v!r}: must be >= 0")
    return int(v) if integer else float(v)


DISTRIBUTIONS = ("normal", "uniform")

# The rig's uncertainty (docs/physics.md#the-rigs-uncertainty): how far a built rig may differ from the model, as
# [model_options.noise] keys. Stated estimates (nothing here is a measured tolerance): each band's stiffness
# x[0.85, 1.15], honey viscosity x[0.7, 1.3], inertias x[0.9, 1.1], a hand push's magnitude x[0.7, 1.3] and its
# timing +-50 ms, each uniform. `design` searches and verifies under it, `robustness` reports the shipped scenes
# under it; `--set model_options.noise.KEY=VALUE` with these values gives any run the same draws.
RIG_UNCERTAINTY = {
    "distribution": "uniform",
    "band_spread": 0.15,
    "eta_spread": 0.3,
    "inertia_spread": 0.1,
    "push_spread": 0.3,
    "push_timing_s": 0.05,
}


def rig_noise_overrides(seed: int) -> list[str]:
    """The --set items giving a run the rig's uncertainty (RIG_UNCERTAINTY) drawn with this seed."""
    return [f"model_options.noise.seed={seed}"] + [f"model_options.noise.{k}={v}" for k, v in RIG_UNCERTAINTY.items()]


def parse_noise(d: dict, prefix: str = "model_options.noise") -> NoiseOptions:
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix}: expected a table")
    known = {f.name for f in fields(NoiseOptions)}
    for k in d:
        if k not in known:
            raise ConfigError(f"unknown key {prefix}.{k}; known: {', '.join(sorted(known))}")
    kw = {}
    for k, v in d.items():
        if k == "seed":
            kw[k] = _num(f"{prefix}.seed", v, integer=True, nonneg=True)
        elif k == "distribution":
            if v not in DISTRIBUTIONS:
                raise ConfigError(f"{prefix}.{k} = {v!r}: expected one of {', '.join(DISTRIBUTIONS)}")
            kw[k] = v
        elif k == "encoder_glitch_prob":
            kw[k] = _num(f"{prefix}.{k}", v, nonneg=True)
            if kw[k] > 1:
                raise ConfigError(f"{prefix}.{k} = {v!r}: a probability must be <= 1")
        else:
            kw[k] = _num(f"{prefix}.{k}", v, nonneg=True)
    return NoiseOptions(**kw)


def parse_image(d: dict, prefix: str = "model_options.image") -> ImageOptions:
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix}: expected a table")
    known = {f.name for f in fields(ImageOptions)}
    kw: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}.{k}"
        if k not in known:
            raise ConfigError(f"unknown key {key}; known: {', '.join(sorted(known))}")
        if k == "threads":
            kw[k] = _num(key, v, integer=True, positive=True)
            if kw[k] > IMAGE_THREADS_MAX:
                raise ConfigError(f"{key} = {v!r}: expected 1..{IMAGE_THREADS_MAX}")
        elif k == "cycle_model":
            if v not in CYCLE_MODELS:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(CYCLE_MODELS)}")
            kw[k] = v
        elif k == "pwm":
            if v not in PWM_PATHS:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(PWM_PATHS)}")
            kw[k] = v
        elif k in ("fast_forward", "fast_forward_timed", "motor_inductance"):
            if not isinstance(v, bool):
                raise ConfigError(f"{key} = {v!r}: expected true or false")
            kw[k] = v
        elif k == "boot":
            if v not in BOOT_MODES:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(BOOT_MODES)}")
            kw[k] = v
        elif k == "round_s":
            kw[k] = _num(key, v, nonneg=True)
            if kw[k] > 0.01 or 0 < kw[k] < IMAGE_ROUND_MIN_S:
                raise ConfigError(
                    f"{key} = {v!r}: expected 0 (the plant window) or {IMAGE_ROUND_MIN_S:g} .. 0.01 s (results do not "
                    "depend on it; shorter rounds only cost time)"
                )
    if kw.get("motor_inductance") and kw.get("pwm", "mean") != "waveform":
        raise ConfigError(f'{prefix}.motor_inductance = true: needs {prefix}.pwm = "waveform"')
    return ImageOptions(**kw)


def parse_options(d: dict, prefix: str = "model_options") -> ModelOptions:
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix}: expected a table")
    known = {f.name for f in fields(ModelOptions)}
    kw: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}.{k}"
        if k not in known:
            raise ConfigError(f"unknown key {key}; known: {', '.join(sorted(known))}")
        if k == "noise":
            kw[k] = parse_noise(v, key)
        elif k == "image":
            kw[k] = parse_image(v, key)
        elif k == "inertia":
            if not isinstance(v, bool):
                raise ConfigError(f"{key} = {v!r}: expected true or false")
            kw[k] = v
        elif k in _CHOICES:
            if v not in _CHOICES[k]:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(_CHOICES[k])}")
            kw[k] = v
        elif k == "stepper":
            if not isinstance(v, str) or v not in STEPPERS:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(sorted(STEPPERS))}")
            kw[k] = v
        elif k in ("dt", "dt_out"):
            kw[k] = _num(key, v, positive=True)
        elif k == "tol":
            kw[k] = _num(key, v, positive=True)
            if not TOL_RANGE[0] <= kw[k] <= TOL_RANGE[1]:
                raise ConfigError(f"{key} = {v!r}: expected {TOL_RANGE[0]:g} <= tol <= {TOL_RANGE[1]:g}")
        elif k in ("substeps", "points_per_cell"):
            kw[k] = _num(key, v, integer=True, positive=True)
    return ModelOptions(**kw)


@dataclass(frozen=True)
class Perturbation:
    """External torque on one cylinder: cell is 1-based, torque in N*m, active start_s <= t < start_s + duration_s.
    On a sheet a push may name its place as (row, col) (1-based): cell is then topology.cell_of(row, col), and the
    record keeps row and col as the scene gave them (row = col = 0: the scene named the cell)."""

    cell: int
    chain: str
    torque_Nm: float
    start_s: float
    duration_s: float
    row: int = 0
    col: int = 0

    def as_dict(self) -> dict:
        where = {"row": self.row, "col": self.col} if self.row else {"cell": self.cell}
        return {
            **where,
            "chain": self.chain,
            "torque_Nm": self.torque_Nm,
            "start_s": self.start_s,
            "duration_s": self.duration_s,
        }


_PERT_KEYS = ("cell", "chain", "torque_Nm", "start_s", "duration_s")
_PLACE_KEYS = ("row", "col")  # a sheet's (row, col) instead of cell


def cell_at(d: dict, cells: Any, where: str) -> tuple[int, int, int]:
    """(cell, row, col) of a table naming its cell as cell = N (1..n), or on a sheet as row = R, col = C (1-based,
    exclusive with cell; row = col = 0 when the table gave cell). cells: the number of cells, or the Topology."""
    n = cells if isinstance(cells, int) else cells.n
    sheet = not isinstance(cells, int) and cells.is_sheet
    given = [k for k in _PLACE_KEYS if k in d]
    if given and not sheet:
        raise ConfigError(f"{where}.{given[0]}: a chain names its cells by cell = 1..{n} (row and col: a sheet's)")
    if given:
        if "cell" in d:
            raise ConfigError(f"{where}: give cell or row and col, not both")
        if len(given) == 1:
            other = "col" if given[0] == "row" else "row"
            raise ConfigError(f"{where}: {given[0]} without {other} (a sheet's cell is row and col, or cell)")
        r = _num(f"{where}.row", d["row"], integer=True)
        c = _num(f"{where}.col", d["col"], integer=True)
        if not 1 <= r <= cells.rows:
            raise ConfigError(f"{where}.row = {r}: must be in 1..{cells.rows}")
        if not 1 <= c <= cells.cols:
            raise ConfigError(f"{where}.col = {c}: must be in 1..{cells.cols}")
        return cells.cell_of(r, c), r, c
    if "cell" not in d:
        raise ConfigError(f"{where}: missing key cell" + (" (or row and col)" if sheet else ""))
    cell = _num(f"{where}.cell", d["cell"], integer=True)
    if not 1 <= cell <= n:
        raise ConfigError(f"{where}.cell = {cell}: must be in 1..{n}")
    return cell, 0, 0


def parse_perturbation(d: dict, cells: Any, where: str) -> Perturbation:
    """A [[perturbation]] table. cells: the number of cells (a chain), or the scene's Topology (a sheet's pushes may
    say row and col instead of cell)."""
    if not isinstance(d, dict):
        raise ConfigError(f"{where}: expected a table")
    sheet = not isinstance(cells, int) and cells.is_sheet
    known = _PERT_KEYS + (_PLACE_KEYS if sheet else ())
    for k in d:
        if k not in known:
            raise ConfigError(f"unknown key {where}.{k}; known: {', '.join(known)}")
    placed = any(k in d for k in _PLACE_KEYS)  # row and col stand for cell
    missing = [k for k in _PERT_KEYS if k not in d and not (k == "cell" and placed)]
    if missing:
        raise ConfigError(f"{where}: missing key(s) {', '.join(missing)}")
    cell, row, col = cell_at(d, cells, where)
    if d["chain"] not in CHAINS:
        raise ConfigError(f"{where}.chain = {d['chain']!r}: expected alpha or beta")
    return Perturbation(
        cell,
        d["chain"],
        _num(f"{where}.torque_Nm", d["torque_Nm"]),
        _num(f"{where}.start_s", d["start_s"], nonneg=True),
        _num(f"{where}.duration_s", d["duration_s"], nonneg=True),
        row,
        col,
    )


# ---- faults injected into the image model's boards ([[fault]] of a scene) --------------------------------------
FAULT_KINDS = {
    # kind: (what it does, keys it takes besides kind and start_s)
    "edge_storm": (
        "glitch pairs on one encoder's A channel of a cell (a bad cable)",
        ("cell", "chain", "rate_hz", "duration_s"),
    ),
    "stuck_sda": ("the bus's SDA held low (a latched-up part)", ("duration_s",)),
    "silent": ("a board loses power, then powers up again", ("board", "duration_s")),
    "usb_no_read": ("the laptop stops reading the primary's USB port", ("duration_s",)),
    "hardfault": ("a HardFault on a board, as a bad pointer gives", ("board",)),
    "tick_dead": ("a cell's TC3 loses its clock: the control tick stops", ("cell",)),
}
EDGE_STORM_MAX_HZ = 400_000.0


@dataclass(frozen=True)
class Fault:
    """A fault on the image model's boards from scene time start_s (s after the cells were configured)."""

    kind: str
    start_s: float
    board: str = ""  # "primary" or "cellN" (edge_storm and tick_dead: a cell; silent, hardfault: any board)
    duration_s: float = 0.0
    chain: str = "alpha"
    rate_hz: float = 0.0

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("kind", "start_s", "board", "duration_s", "chain", "rate_hz")}


FAULT_MAX_S = 1e6  # s: a fault's start and duration (11.6 days, far beyond any image run's t_end_s)


def _fault_time(key: str, v, **kw) -> float:
    """A fault's time in s: a finite number within FAULT_MAX_S (the boards count time in clock cycles: 1e15 s or
    1e300 s would overflow them long after the run started)."""
    t = _num(key, v, **kw)
    if t > FAULT_MAX_S:
        raise ConfigError(f"{key} = {v!r}: at most {FAULT_MAX_S:g} s")
    return t


def parse_fault(d: dict, cells: Any, where: str) -> Fault:
    """A [[fault]] table: kind, start_s, and the keys its kind takes (FAULT_KINDS); cell = N or board = "primary"
    | "cellN" name the board."""
    if not isinstance(d, dict):
        raise ConfigError(f"{where}: expected a table")
    kind = d.get("kind")
    if not isinstance(kind, str) or kind not in FAULT_KINDS:  # (a table or an array is no kind, and no dict key)
        raise ConfigError(f"{where}.kind = {kind!r}: expected one of {', '.join(FAULT_KINDS)}")
    takes = FAULT_KINDS[kind][1]
    allowed = {"kind", "start_s", *takes} | ({"cell"} if "board" in takes else set())
    if "cell" in allowed and not isinstance(cells, int) and cells.is_sheet:
        allowed |= set(_PLACE_KEYS)  # a sheet's cell as row and col
    n = cells if isinstance(cells, int) else cells.n
    for k in d:
        if k not in allowed:
            raise ConfigError(f"{where}.{k}: a {kind} fault takes {', '.join(sorted(allowed))}")
    if "start_s" not in d:
        raise ConfigError(f"{where}: missing key start_s")
    kw: dict[str, Any] = {"kind": kind, "start_s": _fault_time(f"{where}.start_s", d["start_s"], nonneg=True)}
    if "cell" in d and "board" in d:
        raise ConfigError(f"{where}: give cell or board, not both")
    if "cell" in takes or "board" in takes:
        if "cell" in d or any(k in d for k in _PLACE_KEYS):
            kw["board"] = f"cell{cell_at(d, cells, where)[0]}"
        elif "board" in d:
            b = d["board"]
            ok = b == "primary" or (isinstance(b, str) and re.fullmatch(r"cell[1-9][0-9]{0,5}", b) is not None)
            ok = ok and (b == "primary" or 1 <= int(b[4:]) <= n)  # ASCII digits, no leading zero: cell7
            if not ok or "cell" in takes:
                want = f"cell1..cell{n}" + ("" if "cell" in takes else " or primary")
                raise ConfigError(f"{where}.board = {b!r}: expected {want}")
            kw["board"] = b
        else:
            raise ConfigError(f"{where}: a {kind} fault needs " + ("cell" if "cell" in takes else "cell or board"))
    if "duration_s" in takes:
        if "duration_s" not in d:
            raise ConfigError(f"{where}: a {kind} fault needs duration_s")
        kw["duration_s"] = _fault_time(f"{where}.duration_s", d["duration_s"], positive=True)
    if kind == "edge_storm":
        if d.get("chain", "alpha") not in CHAINS:
            raise ConfigError(f"{where}.chain = {d['chain']!r}: expected alpha or beta")
        kw["chain"] = d.get("chain", "alpha")
        if "rate_hz" not in d:
            raise ConfigError(f"{where}: an edge_storm fault needs rate_hz")
        kw["rate_hz"] = _num(f"{where}.rate_hz", d["rate_hz"], positive=True)
        if kw["rate_hz"] > EDGE_STORM_MAX_HZ:
            raise ConfigError(f"{where}.rate_hz = {d['rate_hz']!r}: at most {EDGE_STORM_MAX_HZ:g} glitch pairs per s")
    return Fault(**kw)
