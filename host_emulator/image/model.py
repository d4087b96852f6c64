"""The `image` model: the flashed cell and primary images on the plant, configured over USB and I2C by a laptop.

A run goes as on the rig: the 17 boards power up at world time 0 (the XIAO's 32.768 kHz crystal takes 2 s to
start); the laptop plugs the primary's USB in, opens the port and, over SLCAN and the I2C bus, configures every
cell as the experiment runner does (drive off, the scene's reaction-law parameters, PWM limit, back-EMF
compensation, faults cleared, zero, drive on); the scene's time 0 is when the last cell confirmed its drive on.
The angles are the plant's (as the lattice and hil models report theirs); the cells' faults come from their
CELL_STATUS frames, as the laptop sees them.
"""

from __future__ import annotations

import gc
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from protocol import codec
from protocol import definition as d

from ..models.hil import REACTION_FIELDS, reaction_problem
from ..models.lattice import LatticeModel
from ..models.options import ConfigError, Fault, ModelOptions, Perturbation
from ..models.plant import choose_step
from ..models.solver import Solver
from ..params import Params
from ..progress import bar
from . import ImageTierUnavailable
from .build import build_images
from .laptop import Laptop, LaptopError
from .world import MOTOR_TAU_S, World, WorldConfig, WorldError

# the flashed build's control rate and PWM period (platformio.ini: MC_CTRL_RATE_HZ, MC_PWM_TOP)
BUILD_CTRL_RATE_HZ = 2000
BUILD_PWM_TOP = 2400
WINDOW_S = 50e-6  # the plant's window (world.WorldConfig.window_s)


def setup_commands(p: Params) -> list[tuple[str, dict]]:
    """The commands that configure a cell for the scene, in the order the rig's experiment runner sends them (p: that
    cell's scalar parameters, Params.cell(j))."""
    cmds: list[tuple[str, dict]] = [("ENABLE", {"on": 0})]
    for name, _member, reg in REACTION_FIELDS:
        cmds.append((reg, {"value": codec.to_register(reg, "value", getattr(p, name), firmware=False)}))
    ticks = round(min(p.vmax_v, p.supply_v) / p.supply_v * BUILD_PWM_TOP)
    cmds += [
        ("PWM_LIMIT", {"ticks": ticks}),
        ("BEMF", {"on": int(bool(p.bemf_comp))}),
        ("CLEAR_FAULTS", {}),
        ("ZERO", {}),
        ("ENABLE", {"on": 1}),
    ]
    return cmds


def bring_up(world: World, params: Params, progress: bool = False) -> tuple[Laptop, dict]:
    """As on the rig: the laptop plugs the primary's USB in (the boards boot meanwhile: the crystal takes 2 s), opens
    the port and configures every cell with the scene's commands (setup_commands), the drive on last. Returns the
    laptop and what happened (USB enumerated at, refused commands). LaptopError / WorldError when it cannot."""
    cells = list(range(1, params.cells + 1))
    per_cell = {j: setup_commands(params.cell(j)) for j in cells}  # per-cell reaction values: each cell its own
    n_steps = len(per_cell[1])
    lap = Laptop(world)
    refused: dict[str, dict[int, str]] = {}
    with bar(2 + n_steps, desc="image: boot, USB, configure", unit="step", quiet=not progress) as pb:
        t_usb = lap.plug()
        pb.update()
        lap.open()
        pb.update()
        for k in range(n_steps):
            reg = per_cell[1][k][0]
            groups: dict[tuple, list[int]] = {}  # cells that take the same values get one command together
            for j in cells:
                groups.setdefault(tuple(sorted(per_cell[j][k][1].items())), []).append(j)
            res: dict[int, str] = {}
            for values, group in groups.items():
                res.update(lap.command(group, reg, **dict(values)))
            pb.update()
            bad = {j: r for j, r in res.items() if r != "OK"}
            if bad:
                refused[reg] = bad
                break
    return lap, {"usb_enumerated_s": t_usb, "refused": refused}


def encoder_noise_problem(opts: ModelOptions) -> str | None:
    """The tier's encoders are the plant's own quadrature edges at the pins: encoder noise is refused (one line)."""
    nz = opts.noise
    for key in ("encoder_jitter_counts", "encoder_glitch_prob"):
        if getattr(nz, key):
            return (
                f"model_options.noise.{key} = {getattr(nz, key)}: the image tier's encoders are the plant's own "
                "quadrature edges at the boards' pins and take no encoder noise (its plant takes band_spread and "
                "eta_spread; [[fault]] edge_storm puts glitches on a cable); model = hil samples a noisy encoder"
            )
    return None


class ImageModel(LatticeModel):
    """The lattice plant driven by the flashed images (module docstring). Physics from the lattice model (its step
    limit judges the plant's window); the reaction torque reaches the plant only through the motors."""

    name = "image"
    ideal_reaction = False

    def __init__(
        self, params: Params, perturbations: Sequence[Perturbation] = (), options: ModelOptions | None = None
    ) -> None:
        opts = options or ModelOptions()
        super().__init__(params, perturbations if opts.perturb_via == "plant" else [], opts)
        self.all_perturbations = list(perturbations)
        if not 1 <= params.cells <= 16:
            raise ConfigError(f"cells = {params.cells}: the rig's bus has 16 cells (the image model runs 1..16)")
        if round(params.control_rate_hz) != BUILD_CTRL_RATE_HZ or int(params.pwm_top) != BUILD_PWM_TOP:
            raise ConfigError(
                f"params.control_rate_hz = {params.control_rate_hz}, params.pwm_top = {params.pwm_top}: the flashed "
                f"images are built for {BUILD_CTRL_RATE_HZ} Hz and a PWM period of {BUILD_PWM_TOP} (platformio.ini)"
            )
        problem = reaction_problem(params)  # the values every cell's firmware would refuse, as hil judges them
        if problem:
            raise ConfigError(problem)
        problem = encoder_noise_problem(opts)
        if problem:
            raise ConfigError(problem)

        self.faults: tuple[Fault, ...] = ()

    def inject(self, faults: Sequence[Fault]) -> None:
        """Faults to inject into the boards, at scene times (controller.build_solver passes a scene's [[fault]])."""
        self.faults = tuple(faults)

    def solver(self, x0: ArrayLike | None = None, v0: ArrayLike | None = None) -> ImageSolver:  # type: ignore[override]
        return ImageSolver(self, x0, v0)


class ImageSolver(Solver):
    """Boots the boards, configures the cells over the bus, then advances in output samples of whole windows."""

    model: ImageModel

    def __init__(
        self,
        model: ImageModel,
        x0: ArrayLike | None = None,
        v0: ArrayLike | None = None,
        config: WorldConfig | None = None,
    ) -> None:
        self.model = model
        p, opt = model.params, model.options
        limit, chain = model.step_limit()
        self.limit, self.limit_chain = limit, chain
        io = opt.image
        cfg = config or WorldConfig(
            window_s=WINDOW_S,
            threads=io.threads,
            cycle_model=io.cycle_model,
            ff=io.fast_forward,
            ff_timed=io.fast_forward_timed,
            round_s=io.round_s,
            boot=io.boot,
            pwm=io.pwm,
            motor_tau_s=MOTOR_TAU_S if io.motor_inductance else 0.0,
        )
        if opt.substeps is not None:
            cfg.substeps = opt.substeps
            if cfg.window_s / cfg.substeps > limit:
                raise ConfigError(
                    f"model_options.substeps = {opt.substeps}: plant step {cfg.window_s / opt.substeps:.4g} s exceeds "
                    f"the stable limit {limit:.4g} s of stepper {opt.stepper!r} ({chain} chain)"
                )
        else:
            _, cfg.substeps = choose_step(limit, cfg.window_s, opt.dt, opt.stepper, chain)
        windows = max(1, round(opt.dt_out / cfg.window_s))
        self.dt_out = windows * cfg.window_s
        self.adjusted: list[str] = []  # what the tier changed of the options given (info, the run's output)
        if not math.isclose(self.dt_out, opt.dt_out, rel_tol=1e-9):
            self.adjusted.append(
                f"model_options.dt_out = {opt.dt_out:g} s is output every {self.dt_out:g} s: whole plant windows of "
                f"{cfg.window_s:g} s"
            )
        try:
            images = build_images(p.cells)
            self.world = World(p, images, options=opt, perturbations=model.perturbations, config=cfg, x0=x0)
        except ImageTierUnavailable as e:
            raise ConfigError(f"image: {e}") from None
        except WorldError as e:
            raise ConfigError(f"image: {e}") from None
        if v0 is not None:
            self.world.v[:] = np.asarray(v0, dtype=float).reshape(2 * p.cells)
        self.cells = list(range(1, p.cells + 1))
        self.preamble: dict = {}
        self._configure()
        self._inject(model.faults)
        self.t = 0.0
        self.events: list[tuple[float, int, dict]] = []
        if opt.perturb_via == "firmware":
            for q in model.all_perturbations:
                torque = codec.to_register("PERTURB", "torque", q.torque_Nm)
                ticks = max(1, round(q.duration_s * BUILD_CTRL_RATE_HZ))
                self.events.append(
                    (q.start_s, q.cell, {"chain": 0 if q.chain == "alpha" else 1, "torque": torque, "ticks": ticks})
                )
            self.events.sort(key=lambda e: (e[0], e[1]))

    def _configure(self) -> None:
        try:
            self.laptop, up = bring_up(self.world, self.model.params, progress=True)
        except (LaptopError, WorldError) as e:
            raise ConfigError(f"image: the boards could not be brought up: {e}") from None
        if up["refused"]:
            raise ConfigError(f"image: the cells refused the scene's configuration: {up['refused']}")
        self.t_start = self.world.start_plant()
        self.preamble = {"usb_enumerated_s": up["usb_enumerated_s"], "scene_start_s": self.t_start}
        # What exists now (the world, the images, numpy and scipy) lives for the whole run: the cyclic garbage
        # collector stops scanning it (a full collection walked all of it, 2-8 % of the run's instructions under
        # callgrind, at times no one chose; docs/image-tier.md, "Speed").
        gc.freeze()

    def _inject(self, faults: Sequence[Fault]) -> None:
        w = self.world
        names = {f"cell{b.cell}": b.index for b in w.boards if b.cell} | {
            "primary": w.primary.index if w.primary else -1
        }
        self.fault_slots: list[int] = []  # each scene fault's index in the world's fault table
        for f in faults:
            t0 = self.t_start + f.start_s
            self.fault_slots.append(w.nfaults())
            board = names.get(f.board, -1)
            if f.kind == "usb_no_read":
                board = names["primary"]
            w.fault(
                f.kind,
                t0,
                t0 + f.duration_s,
                board=board,
                arg=f.rate_hz,
                arg2=0 if f.chain == "alpha" else 1,
            )

    def _fault_records(self) -> dict:
        """The scene's faults as they went: those that took effect (faults_injected, each with fired_s, the scene
        time it did: later than start_s when its board had no power at start_s) and those that did not, the run
        having ended first (faults_unfired)."""
        fired, unfired = [], []
        for f, k in zip(self.model.faults, getattr(self, "fault_slots", ()), strict=False):
            got = self.world.fault_fired(k)
            if got is not None and got[0] == f.kind and got[2] is not None:
                fired.append({**f.as_dict(), "fired_s": round(got[2] - self.t_start, 9)})
            else:
                unfired.append(f.as_dict())
        return {"faults_injected": fired, **({"faults_unfired": unfired} if unfired else {})}

    def plant_step_s(self) -> float:
        """The plant's step: its window split into substeps (the boards' cost is judged by limits.check_run)."""
        return self.world.config.window_s / self.world.config.substeps

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.model.n
        return self.world.x[:n].copy(), self.world.x[n:].copy()

    def advance(self) -> None:
        t_next = self.t + self.dt_out
        while self.events and self.events[0][0] < t_next:
            t_ev, cell, values = self.events.pop(0)
            if t_ev > self.t:
                self.laptop.pump(t_ev - self.t)
            self.laptop.seq = (self.laptop.seq + 1) & 0xFF
            from protocol import wire

            self.laptop.send(wire.cmd_frame_id(cell), wire.cmd_data("PERTURB", self.laptop.seq, **values))
            self.t = max(self.t, t_ev)
        try:
            self.laptop.pump(self.t_start + t_next - self.world.t)
        except WorldError as e:
            from ..models.plant import NumericalInstability

            raise NumericalInstability(f"image: {e}") from None
        self.t = t_next

    def faults(self) -> list[int]:
        return [int(self.laptop.rx.status(j).get("faults", 0)) for j in self.cells]

    def info(self) -> dict:
        w = self.world
        boards = []
        for b in w.boards:
            i = w.info(b.index)
            boards.append(
                {
                    "board": b.name,
                    "resets": int(i.resets),
                    "reset_cause": reset_cause_names(int(i.reset_cause)),
                    "hardfaults": int(i.hardfaults),
                    "cycles": int(i.cycles),
                    "ff_passes_skipped": int(i.ff_passes_skipped),
                }
            )
        bi = w.bus_info()
        rx = self.laptop.rx
        health = rx.health()
        img = w.boards[0].image
        assert img is not None  # a scene's boards hold images (blank boards are for flashing)
        return {
            "dt_out_s": self.dt_out,
            **({"dt_out_requested_s": self.model.options.dt_out, "adjusted": self.adjusted} if self.adjusted else {}),
            "window_s": w.config.window_s,
            "plant_steps_per_window": w.config.substeps,
            "stable_step_limit_s": self.limit,
            "limit_chain": self.limit_chain,
            "perturb_via": self.model.options.perturb_via,
            "images": {"cell": str(img.path.parent.parent), "digest": img.sha256[:16]},
            **self.preamble,
            **self._fault_records(),
            "boards": boards,
            "bus": {"transactions": int(bi.transactions), "nacks": int(bi.nacks), "timeouts": int(bi.timeouts_seen)},
            "laptop": {
                "cell_samples": rx.samples,
                "frames": dict(rx.frames),
                # what the rig's tools would see: the last status and link frames of each cell, the primary's health
                "cell_status": {j: rx.status(j) for j in self.cells if rx.status(j)},
                "cell_link": {j: rx.link(j) for j in self.cells if rx.link(j)},
                "primary_health": {
                    **health,
                    **({"reset_cause": reset_cause_names(int(health["reset_cause"]))} if health else {}),
                },
            },
            "notes": w.notes()[-20:],
        }


def reset_cause_names(bits: int) -> list[str]:
    """RESET_CAUSE bits (PM.RCAUSE as the firmware reports it) as names, from the one protocol definition."""
    return [name for name, bit in d.RESET_CAUSE.items() if bits >> bit & 1]
