"""Issue 30's acceptance on sheets, as tests: the 16 x 16 sheet's wavelength against the 2-D linear theory in the
lattice and the hil, and pattern2d's kind on simulated regimes (docs/patterns2d.md#simulated-regimes).

Why 3 s of the 16 x 16 scene, not its 25 s: the push grows to saturation (max |alpha| 0.69 rad) by 0.5 s and
pattern2d's dominant wavelength is established by 2 s. Measured with `run sheet_16x16 --set t_end_s=25` read at
each time (`python -m host_emulator.benchmarks.sheet_acceptance` runs the full 25 s): lattice 9.373 cells at 2 s,
9.373 at 3 and 4 s (unchanged to 1e-5 cells until 10 s), 9.464 settled at 25 s after the slow transition at
10-18 s (the early one 1.0 % shorter); hil 9.515 at 2, 3, 4 and 25 s (it keeps the first pattern). Against the
fastest-growing wavelength along the axis (lattice 9.859, hil 10.256 cells with the motors' back-EMF damping):
-4.9 % (3 s) and -4.0 % (25 s) in the lattice, -7.2 % in the hil, all inside the annulus (5.79-21.56 cells). The
lattice's `fast` preset gives the same figures to 1e-6 cells as `balanced` at about a third of the CPU; the two
runs together cost about 0.4 s of CPU."""

from __future__ import annotations

import math

import numpy as np
import pytest

import host_emulator as he
from host_emulator.analysis import sheet
from host_emulator.benchmarks.sheet_acceptance import seeded_stripes_toml

EARLY_S = 3.0  # the wavelength is established by 2 s (module docstring); 3 s leaves a margin
WITHIN = 0.25  # the acceptance's: within 25 % of the fastest-growing wavelength


def wavelength_against_theory(r: he.RunResult) -> dict:
    """The run's dominant wavevector read against the 2-D linear theory of its own model (inertia, the hil's motor
    damping): whether the lattice symbol at k* lies in an unstable q-interval (the annulus, in every direction),
    the annulus along k*'s nearer high-symmetry direction, and the relative distance from the fastest wavelength
    along the axis."""
    s = r.summary
    th = r.theory
    an = sheet.annulus(r.scene.params, th)
    fa = sheet.fastest(r.scene.params, th)
    kr, kc = s["dominant_wavevector"]
    q = float(sheet.symbol(r.scene.topology.kind, kr, kc))
    in_q = any(lo < q < hi for lo, hi in (iv["q"] for iv in an["intervals"] if iv["kind"] == "stationary"))
    lam = s["dominant_wavelength_cells"]
    return {
        "lambda": lam,
        "q": q,
        "in_annulus": in_q,
        "annulus_axis": an["intervals"][0]["discrete"]["axis"]["lambda_cells"],
        "fastest": fa["lambda_cells"],
        "relative": lam / fa["lambda_cells"] - 1.0,
    }


@pytest.mark.parametrize("model", ["lattice", "hil"])
def test_a_pushed_16x16_sheet_grows_the_linear_theorys_wavelength(model):
    r = he.run("sheet_16x16", {"t_end_s": EARLY_S, "model": model}, accuracy="fast")
    assert r.scene.topology.shape == (16, 16) and math.isclose(r.scene.params.sigma, 9 / 125)
    assert r.summary["pattern_kind"] in ("stripes", "labyrinth", "spots")  # a pattern, not rest nor oscillation
    got = wavelength_against_theory(r)
    assert got["in_annulus"], got
    lo, hi = got["annulus_axis"]
    assert lo < got["lambda"] < hi, got
    assert abs(got["relative"]) <= WITHIN, got
    # the theory is the model's own: the hil's back-EMF damping moves its fastest wavelength
    assert (r.theory.motor_damping > 0) == (model == "hil")


# ---- the classifier on simulated regimes (docs/patterns2d.md#simulated-regimes) ---------------------------------
def test_the_8x8_sheet_smaller_than_its_wavelength_does_not_read_as_spots():
    """sheet_8x8 settles (from 1.6 s) into one curved band on a sheet smaller than its wavelength: three sign
    domains, all touching an edge; its spectrum's six-fold order is no evidence of spots (docs/patterns2d.md)."""
    r = he.run("sheet_8x8", {"t_end_s": 3.0}, accuracy="fast")
    s = r.summary
    assert s["dominant_wavelength_cells"] > 8
    assert s["pattern_kind"] == "labyrinth"


def test_a_sheet_seeded_with_one_mode_along_the_rows_reads_as_stripes_along_them(tmp_path):
    path = tmp_path / "stripes_seeded.toml"
    path.write_text(seeded_stripes_toml())  # 64 pushes on columns 1, 5, 9, 13, a 5 % band spread per cell
    r = he.run(str(path), accuracy="fast")
    g = r.scene.topology.grid(r.alpha[-1])
    assert np.abs(g).max() > 0.5  # grown and saturated
    assert np.abs(g - g[0]).max() > 1e-6  # the rows differ (the band spread): not a 1-D field by construction
    s = r.summary
    assert s["pattern_kind"] == "stripes"
    assert s["dominant_wavelength_cells"] == pytest.approx(8.0) and s["orientation_deg"] == pytest.approx(0.0)
    # stripes in the field itself: every cell beyond the wall threshold has the sign of the seeded mode's column
    seed = np.cos(2 * np.pi * np.arange(16) / 8)
    big = np.abs(g) > 0.1
    assert (np.sign(g) == np.sign(seed)[None, :])[big].all() and big[:, np.abs(seed) > 0.5].all()
    assert s["defects"] == 0


def test_a_16x16_sheet_at_14_125_rests_in_the_hil_and_oscillates_in_the_lattice():
    """sigma = 14/125: the ideal lattice with inertia is oscillatory-unstable at long waves (the uniform mode,
    period 29 ms), the hil's uncompensated motors damp it (docs/emulator.md, back-EMF): the same sheet and push
    read as an oscillation in one tier and rest in the other."""
    over = {"params.sigma": 14 / 125, "t_end_s": 2.0}
    lat = he.run("sheet_16x16", over, accuracy="fast")
    assert lat.summary["pattern_kind"] == "oscillation"
    period = sheet.fastest(lat.scene.params, lat.theory)["period_s"]
    assert lat.summary["oscillation_period_s"] == pytest.approx(period, rel=0.05)
    hil = he.run("sheet_16x16", {**over, "model": "hil", "t_end_s": 3.0})
    assert hil.summary["pattern_kind"] == "rest"
    assert hil.summary["dominant_wavelength_cells"] is None


def test_a_16x16_sheet_at_6_125_grows_a_spot_around_the_push():
    """sigma = 6/125, where the unstable band reaches the longest waves (broadband): the central push's own round
    bump grows into one compact + domain in a - sheet (a spot, 13.7 cells across, by 1 s, unchanged to 25 s;
    the sweep of docs/workbench.md reads spots at 5/125 to 7/125). It is the push's shape that makes it round: the
    law is odd and favours no spots (docs/sheets.md#stripes-or-spots)."""
    from host_emulator.analysis import pattern2d

    r = he.run("sheet_16x16", {"params.sigma": 6 / 125, "t_end_s": 2.0}, accuracy="fast")
    assert r.summary["pattern_kind"] == "spots"
    topo = r.scene.topology
    sign = pattern2d.sign_field(r.alpha[-1], topo)
    labels, compact = pattern2d.domains(sign, topo)
    centre = topo.cell_of(8, 8) - 1
    assert compact[labels[centre]]  # the pushed cell sits inside a domain that touches no edge
    inside = labels == labels[centre]
    assert 16 <= inside.sum() <= 128  # a spot, not half the sheet
    assert np.all(sign[inside] == sign[centre]) and np.mean(sign[~inside] == -sign[centre]) > 0.8
