"""Tiers (models) by what they model, the questions a scene can state (`question = "pattern"` ...), and the choice of
the cheapest tier that answers one (`model = "auto"`, `run --model auto`), with its reason in one line.

The measured figures (cost per simulated second and errors on the default scene) are the ones
`python -m host_emulator.benchmarks.tiers` printed for docs/accuracy.md#tiers; tests/docs/test_tiers_table.py
holds the docs' table, these constants and the command's deterministic figures together.
"""

from __future__ import annotations

from .models.options import ConfigError

# tier -> what it models (docs/accuracy.md#tiers, one cell of the table), cheapest first in what it models
TIERS = {
    "continuum": "the lattice's continuum limit, a reaction-diffusion PDE on a grid of points per cell: no inertia, "
    "the bands as linear diffusion, the full non-linear psi'",
    "lattice": "the cylinders' equations of motion: ideal reaction torque, cubic bands, inertia, honey damping; "
    "no motors, drivers, encoders or firmware",
    "hil": "the lattice plus the compiled cell firmware in closed loop: motors with back-EMF, PWM, 400-count "
    "encoders, the 2 kHz control tick, firmware faults",
    "image": "the hil's plant plus the flashed ELFs on an emulated SAMD21 (cycles, clocks, I2C bus, the primary's "
    "SLCAN over USB, injected faults)",
}
UP = {"continuum": "lattice", "lattice": "hil", "hil": "image"}  # the next tier up (more modelled)

# question -> (what it asks, the tiers that model it, why those)
QUESTIONS = {
    "pattern": (
        "which pattern forms, its period and amplitude",
        ("hil", "image"),
        "the pattern needs the reaction law, the cubic bands and the motors' back-EMF damping (without it the "
        "ideal lattice selects another pattern, 1.3 rad off)",
    ),
    "oscillation": (
        "whether the long waves oscillate, decay or stay at rest",
        ("hil", "image"),
        "the long waves need inertia and the motors' damping, and the quantised loop keeps a limit cycle of a "
        "few counts that only the firmware in the loop shows",
    ),
    "growth": (
        "growth rates of small deflections against the linear theory",
        ("lattice",),
        "growth below one encoder count (15.7 mrad) is invisible to the firmware; the lattice integrates it",
    ),
    "continuum": (
        "the continuum limit (the reaction-diffusion PDE)",
        ("continuum",),
        "only the continuum tier solves the PDE",
    ),
    "bus": (
        "bus and link counters (I2C transactions, SLCAN frames, the primary's schedule)",
        ("image",),
        "only the image runs the primary's own code over an emulated I2C bus and USB port",
    ),
    "timing": (
        "firmware timing (cycles per tick, CPU budget, clocks)",
        ("image",),
        "only the image counts the Cortex-M0+ cycles of the flashed code",
    ),
    "faults": (
        "injected faults ([[fault]]: stuck SDA, silent board, HardFault, ...)",
        ("image",),
        "only the image injects faults into boards",
    ),
}

# measured by `python -m host_emulator.benchmarks.tiers` (docs/accuracy.md#tiers): default scene, 3 s, balanced
COST_MS_PER_SIM_S = {"continuum": 190.0, "lattice": 2.84, "hil": 1.9, "image": 3147.0}
ERROR_VS_UP_RAD = {"continuum": 0.27, "lattice": 0.64, "hil": 0.11}  # max |alpha - alpha of the next tier up|
# (tier, level) -> max |alpha - alpha at a converged step|, same tier and components (absent: not measured)
PRESET_ERROR_RAD: dict[tuple[str, str], float] = {
    ("lattice", "fast"): 0.00028,
    ("lattice", "balanced"): 7.7e-06,
    ("lattice", "exact"): 1.4e-11,
    ("hil", "fast"): 0.025,
    ("hil", "balanced"): 0.025,
    ("hil", "exact"): 0.0029,
}


def question_of(d: dict) -> str:
    """The question a scene table states (`question`), or "faults" when it has [[fault]] tables; ConfigError if
    neither (model = "auto" needs one)."""
    q = d.get("question")
    if q is None and d.get("fault"):
        q = "faults"
    if q is None:
        raise ConfigError(f"model = 'auto': the scene states no question; set question = one of {', '.join(QUESTIONS)}")
    return check_question(q)


def check_question(q: object) -> str:
    if q not in QUESTIONS:
        from .scene import did_you_mean

        raise ConfigError(f"question = {q!r}{did_you_mean(str(q), QUESTIONS)}: expected one of {', '.join(QUESTIONS)}")
    assert isinstance(q, str)
    return q


def pick(question: str) -> tuple[str, str]:
    """(tier, one-line reason): the cheapest tier (measured cost per simulated second) among those that model the
    question."""
    _what, tiers, why = QUESTIONS[check_question(question)]
    tier = min(tiers, key=lambda t: COST_MS_PER_SIM_S[t])
    cost = f"{fmt_cost(COST_MS_PER_SIM_S[tier])} ms of CPU per simulated s on the default scene"
    dearer = [t for t in tiers if t != tier]
    if dearer:
        cost += " against " + ", ".join(f"{t} {fmt_cost(COST_MS_PER_SIM_S[t])}" for t in dearer)
    return tier, f"model auto -> {tier} for question {question!r}: {why}; {cost} (docs/accuracy.md#tiers)"


def fmt_cost(ms: float) -> str:
    """A cost in ms as the tier table prints it: three significant digits, whole numbers from 100 on."""
    return f"{ms:.0f}" if ms >= 100 else f"{ms:.3g}"
