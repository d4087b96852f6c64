"""Independent floating-point reference of the cell library, written from docs/physics.md#reaction-torques and
#actuators."""

from __future__ import annotations

import math

TU_NM = 2.0**-5 * 1e-6  # one torque unit in N*m
RAD_PER_COUNT = 2 * math.pi / 400
ANGLE_CLAMP = 2048


def clamp(x, lo, hi):
    return lo if x < lo else hi if x > hi else x


def psi_prime_piecewise(g1, g2, astar_counts, x):
    """docs/physics.md#reaction-torques tri-linear psi' with its breakpoint b = k1 a*/(k1 - k2),
    in TU for x in counts."""
    b = g1 * astar_counts / (g1 - g2)
    if x < -b:
        return g1 * (x + astar_counts)
    if x > b:
        return g1 * (x - astar_counts)
    return g2 * x


def reaction(law, alpha, beta):
    """(R_a, R_b) in TU (float) from the fixed-point gains actually held by the firmware."""
    xa = clamp(alpha, -ANGLE_CLAMP, ANGLE_CLAMP)
    xb = clamp(beta, -ANGLE_CLAMP, ANGLE_CLAMP)
    astar = law["astar_q4"] / 16.0
    ra = law["g_ab"] * (xb - xa) - psi_prime_piecewise(law["g1"], law["g2"], astar, xa) - law["g_sigma"] * xb
    rb = law["g_ab"] * (xa - xb)
    return ra, rb


def reaction_si(k_ab, sigma, k1, k2, astar, alpha_rad, beta_rad):
    """docs/physics.md#reaction-torques in SI units (N*m), no quantisation at all."""
    b = k1 * astar / (k1 - k2)
    a = alpha_rad
    psi = k1 * (a + astar) if a < -b else k1 * (a - astar) if a > b else k2 * a
    return k_ab * (beta_rad - a) - psi - sigma * beta_rad, k_ab * (a - beta_rad)


# share of omega/S_L the firmware's compensation adds (MC_BEMF_FRAC_NUM/DEN in mc_drive.h)
BEMF_FRACTION = 15 / 16


def drive_duty(cfg, tau_tu, dtheta_w, bemf_on, window_log2, duty_limit=None):
    """Signed PWM duty (ticks) a perfect real-valued driver would command.

    V = tau/Kt + (15/16) omega/S_L (back-EMF term only if on; the velocity dtheta_w, in
    counts/tick with window_log2 fraction bits, is limited to +-4096), limited to +-vmax,
    duty = round(|V|/V_s * top), capped at floor(vmax*top/V_s) and the user limit.
    """
    vs = cfg["supply_mv"] / 1000.0
    vmax = cfg["vmax_mv"] / 1000.0
    kt = cfg["kt_unm_per_v"] * 1e-6
    sl = cfg["kv_mrad_per_vs"] / 1000.0
    top = cfg["pwm_top"]
    # the torque command saturates at +-2^22 TU (0.131 N*m, three times the stall
    # torque) before conversion: documented in mc_drive.h
    v = clamp(tau_tu, -(1 << 22), 1 << 22) * TU_NM / kt
    if bemf_on:
        dth = clamp(dtheta_w, -4096, 4096)
        omega = dth * RAD_PER_COUNT * cfg["ctrl_rate_hz"] / (1 << window_log2)
        v += BEMF_FRACTION * omega / sl
    v = clamp(v, -vmax, vmax)
    duty = round(abs(v) / vs * top)
    cap = math.floor(cfg["vmax_mv"] * top / cfg["supply_mv"])
    if duty_limit is not None:
        cap = min(cap, duty_limit)
    duty = min(duty, cap)
    return duty if v >= 0 else -duty


class ObserverFloat:
    """Real-valued velocity observer (independent of the C shifts): per tick
    pr = p + v, e = x - pr, p = pr + e/2, v = v + e/8, out = v + e/2, in counts and
    counts/tick; starts at rest at the reset angle."""

    def __init__(self, theta0: float):
        self.p, self.v = float(theta0), 0.0

    def step(self, theta: float) -> float:
        pr = self.p + self.v
        e = theta - pr
        self.p = pr + e / 2
        self.v += e / 8
        return self.v + e / 2


class ObserverInt:
    """The same observer in the firmware's integer formats (Q16 states, floor shifts,
    output counts/tick Q6 clamped to [-4096, 4095]): bit-exact reference for chains."""

    def __init__(self, theta0: int):
        self.p, self.v = clamp(theta0, -2048, 2048) << 16, 0

    def step(self, theta: int) -> int:
        theta = clamp(theta, -2048, 2048)
        pr = self.p + self.v
        e = (theta << 16) - pr
        self.p = pr + (e >> 1)
        self.v += e >> 3
        return clamp((self.v + (e >> 1)) >> 10, -4096, 4095)
