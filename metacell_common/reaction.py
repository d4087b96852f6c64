"""The reaction law's parameters as the firmware holds them: their names, their registers and the defaults every cell
boots with (lib/metacell/src/mc_cell.c). host_emulator.params takes its defaults from here; the command tool's
`apply` fills what a design leaves out with them."""

from __future__ import annotations

import math

#: The reaction law's parameters (docs/physics.md#reaction-torques), each one value or one per cell.
REACTION_KEYS = ("k_ab", "sigma", "k1", "k2", "alpha_star")
#: Parameter -> the register that carries it (protocol/definition.py), in the order the command tool writes them.
REACTION_REGISTERS = {"k_ab": "K_AB", "sigma": "SIGMA", "k1": "K1", "k2": "K2", "alpha_star": "ASTAR"}
#: The pattern-forming (conditional) regime's sigma: the source's experiments and the firmware's default.
SIGMA_MAIN = 9 / 125
#: The source's experiment values, the firmware's defaults: N m / rad (alpha_star in rad).
REACTION_DEFAULTS: dict[str, float] = {
    "k_ab": 1 / 50,
    "k1": 3 / 50,
    "k2": -3 / 50,
    "alpha_star": 3 * math.pi / 8,
    "sigma": SIGMA_MAIN,
}
