"""Hardware-in-the-loop model: the lattice plant driven by the compiled cell firmware via motors, drivers, encoders."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from protocol import codec

from ..params import Params
from .lattice import LatticeModel
from .options import ModelOptions, Perturbation
from .plant import NumericalInstability, choose_step, error_text
from .solver import Solver
from .steppers import stepper_id

# Params field -> (mc_reaction_phys_t member, register carrying the same value on the wire)
REACTION_FIELDS = (
    ("k_ab", "k_ab_unm", "K_AB"),
    ("sigma", "sigma_unm", "SIGMA"),
    ("k1", "k1_unm", "K1"),
    ("k2", "k2_unm", "K2"),
    ("alpha_star", "astar_urad", "ASTAR"),
)


def reaction_phys(ffi, params: Params):
    """mc_reaction_phys_t of scalar Params (one cell's: Params.cell(j)): gains and a* scaled as their registers are
    (protocol.codec: uN*m/rad, urad; the firmware judges the range)."""
    phys = ffi.new("mc_reaction_phys_t *")
    for name, member, reg in REACTION_FIELDS:
        _store(phys, member, lambda n=name, r=reg: codec.si_to_raw(codec.unit_of(r, "value"), getattr(params, n)), name)
    return phys


def reaction_problem(params: Params) -> str | None:
    """The first reaction value the firmware would refuse, as a one-line message naming the key and, for per-cell
    values, the cell (range: |k| <= K_MAX, 0 <= alpha* <= ASTAR_MAX; shape: k1 > max(k2, 0)); None if all pass."""
    per = set(params.per_cell_keys)
    for j in range(1, params.cells + 1):
        c = params.cell(j)
        where = {n: f"params.{n}[{j}] (cell {j})" if n in per else f"params.{n}" for n, _, _ in REACTION_FIELDS}
        for name, _, reg in REACTION_FIELDS:
            v = c.value(name)
            try:
                codec.to_register(reg, "value", v, firmware=True)
            except codec.RangeError as e:
                return f"{where[name]} = {v!r}: {e}"
        k1, k2 = c.value("k1"), c.value("k2")
        if not (k1 > 0 and k1 > k2):
            return (
                f"{where['k1']} = {k1!r}, {where['k2']} = {k2!r}: the firmware needs k1 > max(k2, 0) "
                "(a bistable, continuous psi')"
            )
        if len(per) == 0:
            break  # every cell the same
    return None


def firmware_config(ffi, lib, params: Params):
    """(mc_reaction_phys_t, mc_drive_config_t) from Params: gains and a* scaled as their registers are
    (protocol.codec: uN*m/rad, urad; the firmware judges the range), volts in mV. Per-cell parameters: cell 1's
    reaction (HilModel.cell_phys holds every cell's)."""
    phys = reaction_phys(ffi, params.cell(1))
    drv = ffi.new("mc_drive_config_t *")
    lib.mc_drive_default_config(drv)
    _store(drv, "supply_mv", lambda: round(params.supply_v * 1000), "supply_v")
    _store(drv, "vmax_mv", lambda: round(params.vmax_v * 1000), "vmax_v")
    _store(drv, "kt_unm_per_v", lambda: round(params.kt * 1e6), "kt")
    _store(drv, "kv_mrad_per_vs", lambda: round(params.speed_const * 1000), "speed_const")
    _store(drv, "pwm_top", lambda: int(params.pwm_top), "pwm_top")
    _store(drv, "ctrl_rate_hz", lambda: round(params.control_rate_hz), "control_rate_hz")
    drv.vel_window_log2 = -1
    return phys, drv


def _store(struct, member: str, value, name: str) -> None:
    """struct.member = value(), or a ConfigError naming params.<name> when the firmware's integer cannot hold it
    (cffi's bare "int too big to convert" names nothing)."""
    try:
        setattr(struct, member, value())
    except (OverflowError, ValueError, TypeError) as e:
        from .options import ConfigError

        raise ConfigError(f"params.{name}: does not fit the firmware's integer field {member} ({e})") from None


class HilModel(LatticeModel):
    """Lattice + DRV8874/motor (tau = Kt (V - omega/S_L), PWM duty quantised to pwm_top, DIR, 5.86 V cap in the
    firmware), 400-count quadrature encoders feeding mc_quad_update, and one compiled mc_cell_t per cell ticking
    at params.control_rate_hz. The reaction torque reaches the plant only through the motors."""

    name = "hil"
    ideal_reaction = False

    def __init__(
        self, params: Params, perturbations: Sequence[Perturbation] = (), options: ModelOptions | None = None
    ) -> None:
        super().__init__(params, perturbations if (options or ModelOptions()).perturb_via == "plant" else [], options)
        self.all_perturbations = list(perturbations)
        self.phys, self.drive_cfg = firmware_config(self.ffi, self.lib, params)
        # each cell's firmware instance gets its own reaction law (the same object when the law is uniform)
        self.cell_phys = (
            [reaction_phys(self.ffi, params.cell(j)) for j in range(1, self.n + 1)]
            if params.per_cell_keys
            else [self.phys] * self.n
        )
        problem = reaction_problem(params)
        if problem:
            raise ValueError(f"firmware rejects the reaction parameters: {problem}")
        # trial configuration, so bad parameters fail here with the firmware's verdict
        c = self.ffi.new("mc_cell_t *")
        self.lib.mc_cell_init(c)
        for j, phys in enumerate(self.cell_phys if params.per_cell_keys else [self.phys]):
            if self.lib.mc_cell_set_params(c, phys) != self.lib.MC_OK:
                kmax, amax = self.lib.MC_K_MAX_UNM * 1e-6, self.lib.MC_ASTAR_MAX_URAD * 1e-6
                raise ValueError(
                    f"firmware rejected the reaction parameters of cell {j + 1} (|k| <= {kmax:g} N*m/rad, "
                    f"0 <= alpha_star <= {amax:g} rad, k1 > max(k2, 0)): {params.cell(j + 1)}"
                )
        if self.lib.mc_cell_set_drive(c, self.drive_cfg) != self.lib.MC_OK:
            raise ValueError(
                "firmware rejected the drive configuration (control_rate_hz 100..50000, pwm_top "
                f"255..4095, vmax_v <= {self.lib.MC_VMAX_ABS_MV / 1000:g} and <= supply_v): "
                f"control_rate_hz={params.control_rate_hz}, "
                f"pwm_top={params.pwm_top}, vmax_v={params.vmax_v}, supply_v={params.supply_v}"
            )
        self.rate_hz = int(self.drive_cfg.ctrl_rate_hz)

    def step_limit(self, stepper: str | None = None) -> tuple[float, str]:
        """The smaller of the limits with every motor driving (back-EMF damping Kt/S_L on) and coasting."""
        lims = []
        for g in (0.0, self.params.kt):
            for ch in range(2):  # the plant's row of n motor gains, written in place (a 256 x 256 sheet: 65,536)
                np.frombuffer(self.ffi.buffer(self.plant.mgain[ch], 8 * self.n), dtype=float)[:] = g
            lims.append(super().step_limit(stepper))
        return min(lims)

    # HilModel reuses the lattice physics (forces, step limit) but runs its own tick-based solver
    def solver(self, x0: ArrayLike | None = None, v0: ArrayLike | None = None) -> HilSolver:  # type: ignore[override]
        return HilSolver(self, x0, v0)


class HilSolver(Solver):
    """Runs whole control ticks in C (he_hil_run); Python only applies firmware perturbation commands."""

    model: HilModel

    def __init__(self, model: HilModel, x0: ArrayLike | None = None, v0: ArrayLike | None = None) -> None:
        self.model = model
        ffi, lib = model.ffi, model.lib
        opt = model.options
        n = model.n
        self.stepper = opt.stepper
        self.sid = stepper_id(lib, opt.stepper)
        self.limit, self.limit_chain = model.step_limit()
        tick = 1.0 / model.rate_hz
        if opt.substeps is not None:
            self.substeps = opt.substeps
            if tick / self.substeps > self.limit:
                raise ValueError(
                    f"model_options.substeps = {opt.substeps}: plant step {tick / opt.substeps:.4g} s "
                    f"exceeds the stable limit {self.limit:.4g} s of stepper {opt.stepper!r} "
                    f"({self.limit_chain} chain)"
                )
        else:
            _, self.substeps = choose_step(self.limit, tick, opt.dt, opt.stepper, self.limit_chain)
        self.ticks_per_out = max(1, round(opt.dt_out * model.rate_hz))
        self.dt_out = self.ticks_per_out / model.rate_hz
        nz = opt.noise
        self.cells = ffi.new("mc_cell_t[]", n)
        self.quad = ffi.new("mc_quad_t[]", 2 * n)
        self.count = ffi.new("int32_t[]", 2 * n)
        for j in range(n):
            c = self.cells + j
            lib.mc_cell_init(c)
            lib.mc_cell_set_params(c, model.cell_phys[j])
            lib.mc_cell_set_drive(c, model.drive_cfg)
            lib.mc_cell_set_bemf(c, 1 if model.params.bemf_comp else 0)
        h = ffi.new("he_hil_t *")
        h.n = n
        h.substeps = self.substeps
        h.stepper = self.sid
        h.tick_s = tick
        h.supply_v = model.params.supply_v
        h.kt = model.params.kt
        h.counts_per_rad = lib.MC_COUNTS_PER_REV / (2 * math.pi)
        h.jitter_counts = nz.encoder_jitter_counts
        h.glitch_prob = nz.encoder_glitch_prob
        h.rng = (nz.seed * 0x9E3779B97F4A7C15 + 0x2545F4914F6CDD1D) % (1 << 64) or 1
        h.plant = model.plant
        h.cells = self.cells
        h.quad = self.quad
        h.count = self.count
        top = int(model.drive_cfg.pwm_top)
        self.volt_tab = ffi.new("double[]", top + 1)
        lib.he_hil_volt_table(self.volt_tab, top, h.supply_v)
        h.volt_tab = self.volt_tab
        h.volt_tab_top = top
        self.h = h
        n2 = 2 * n
        self.x = np.zeros(n2) if x0 is None else np.array(x0, dtype=float).reshape(n2)
        self.v = np.zeros(n2) if v0 is None else np.array(v0, dtype=float).reshape(n2)
        self._px = ffi.from_buffer("double[]", self.x)
        self._pv = ffi.from_buffer("double[]", self.v)
        self._pt = ffi.new("double *", 0.0)
        lib.he_hil_sync_encoders(h, self._px)
        for j in range(n):
            # the angle origin (rest) is the encoders' zero; drivers on
            lib.mc_cell_zero(self.cells + j, 0, 0)
            lib.mc_cell_enable(self.cells + j, 1)
        self.events = []
        if opt.perturb_via == "firmware":
            for q in model.all_perturbations:
                # mc_cell_perturb takes uN*m (the wire's PERTURB register carries it in coarser LSBs)
                unm = codec.si_to_raw("uN*m", q.torque_Nm)
                if abs(unm) > lib.MC_PERTURB_MAX_UNM:
                    raise ValueError(
                        f"perturbation torque {q.torque_Nm} N*m: the firmware accepts "
                        f"|torque| <= {lib.MC_PERTURB_MAX_UNM * 1e-6:g} N*m"
                    )
                k0 = round(q.start_s * model.rate_hz)
                self.events.append(
                    (k0, q.cell - 1, 0 if q.chain == "alpha" else 1, unm, max(1, round(q.duration_s * model.rate_hz)))
                )
            self.events.sort()
        self.tick = 0
        self.t = 0.0

    def info(self) -> dict:
        return {
            "stepper": self.stepper,
            "dt_s": 1.0 / self.model.rate_hz / self.substeps,
            "substeps_per_tick": self.substeps,
            "control_rate_hz": self.model.rate_hz,
            "stable_step_limit_s": self.limit,
            "limit_chain": self.limit_chain,
            "dt_out_s": self.dt_out,
            "perturb_via": self.model.options.perturb_via,
            "faults": int(self.h.fault_or),
            "encoder_errors": self.encoder_errors(),
            "glitches_injected": int(self.h.glitches),
        }

    def plant_step_s(self) -> float:
        return 1.0 / self.model.rate_hz / self.substeps

    def encoder_errors(self) -> int:
        return int(sum(self.quad[i].errors for i in range(2 * self.model.n)))

    def faults(self) -> list[int]:
        return [int(self.cells[j].faults) for j in range(self.model.n)]

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.model.n
        return self.x[:n].copy(), self.x[n:].copy()

    def _error(self, rc, samples=None) -> NumericalInstability:
        err = NumericalInstability(
            f"hil: {error_text(self.model.lib, rc)} at t = {self._pt[0]:.6g} s (stepper {self.stepper}, "
            f"{self.substeps} plant steps per control tick, stable limit {self.limit:.3g} s); numerically unstable"
        )
        err.samples = samples
        return err

    def _run(self, nt):
        lib = self.model.lib
        self._pt[0] = self.tick / self.model.rate_hz
        rc = lib.he_hil_run(self.h, nt, self._pt, self._px, self._pv)
        if rc != lib.HE_OK:
            raise self._error(rc)
        self.tick += nt

    def _apply_due_commands(self):
        """Send the firmware perturbation commands due at the current tick (perturb_via = "firmware")."""
        lib = self.model.lib
        while self.events and self.events[0][0] <= self.tick:
            _, j, ch, unm, nt = self.events.pop(0)
            lib.mc_cell_perturb(self.cells + j, ch, unm, nt)

    def run_ticks(self, nt: int = 1):
        """Run nt control ticks (mc_cell_tick of every cell, motors, plant, encoders), sending the scene's
        firmware perturbation commands at their ticks: the public per-tick interface (the bus rig applies its
        register writes between calls). Raises NumericalInstability; then the failing tick is not counted."""
        end = self.tick + int(nt)
        while self.tick < end:
            self._apply_due_commands()
            nxt = min([end] + [e[0] for e in self.events if e[0] > self.tick])
            self._run(nxt - self.tick)
        self.t = self.tick / self.model.rate_hz

    def advance(self):
        self.run_ticks(self.ticks_per_out)

    def advance_many(self, k_max: int):
        """Up to k_max output intervals, bit-identical to as many advance() calls: whole samples free of
        firmware perturbation commands run in one C call (he_hil_run_sampled); a sample with a command inside
        it goes through advance(). Stops early at the first sample that starts or contains a command, so each
        chunk is at least one sample. Returns (t (k,), alpha (k, n), beta (k, n)); on an unstable run raises
        NumericalInstability whose ``samples`` holds the samples completed before the failing one.
        """
        k_max = int(k_max)
        if k_max < 1:
            raise ValueError(f"k_max = {k_max}: must be >= 1")
        m = self.model
        ffi, lib, n, tpo = m.ffi, m.lib, m.n, self.ticks_per_out
        self._apply_due_commands()  # commands due now, as advance() applies them
        free = k_max
        if self.events:  # samples ending at or before the next command
            free = min(free, (self.events[0][0] - self.tick) // tpo)
        if free < 1:  # a command inside the next sample
            self.advance()
            a, b = self.state()
            return np.array([self.t]), a[None, :], b[None, :]
        buf = np.empty((free, 2 * n))
        done = ffi.new("int64_t *", 0)
        tick0 = self.tick
        rc = lib.he_hil_run_sampled(
            self.h, tick0, m.rate_hz, tpo, free, self._pt, self._px, self._pv, ffi.from_buffer("double[]", buf), done
        )
        k = int(done[0])
        t = np.arange(tick0 + tpo, tick0 + (k + 1) * tpo, tpo)[:k] / m.rate_hz  # tick / rate_hz, as advance()
        out = (t, buf[:k, :n], buf[:k, n:])
        self.tick = tick0 + k * tpo
        if rc != lib.HE_OK:
            raise self._error(rc, out)
        self.t = self.tick / m.rate_hz
        return out
