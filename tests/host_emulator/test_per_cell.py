"""Per-cell reaction parameters: scene syntax and errors, every model honours each cell's own law, and a list of equal
values runs bit for bit as the one value."""

import numpy as np
import pytest

from host_emulator import physics
from host_emulator.controller import run_scene
from host_emulator.models import ConfigError, ModelOptions, make_model
from host_emulator.params import Params
from host_emulator.scene import load_scene, scene_table


def _list(v, n=16):
    return "[" + ",".join(repr(float(x)) for x in (v if isinstance(v, (list, tuple)) else [v] * n)) + "]"


@pytest.mark.parametrize(
    "item, words",
    [
        ("params.sigma=[0.07,0.07]", ["params.sigma", "2 values for 16 cells"]),
        ("params.sigma.17=0.05", ["params.sigma.17", "cell 17 outside 1..16"]),
        ("params.alpha_star.3=-1", ["params.alpha_star[3] (cell 3)", ">= 0"]),
        ("params.k2=" + _list([-0.06] * 15 + [float("nan")]), ["params.k2[16] (cell 16)", "finite"]),
    ],
)
def test_bad_per_cell_values_are_one_line_errors_naming_key_and_cell(item, words):
    with pytest.raises(ConfigError) as e:
        load_scene("default", [item])
    msg = str(e.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_firmware_range_per_cell_names_the_cell():
    sc = load_scene("default", ["params.sigma.5=0.3"])
    with pytest.raises(ValueError, match=r"params\.sigma\[5\] \(cell 5\) = 0\.3: .*0\.25"):
        run_scene(sc, progress=False)
    sc = load_scene("default", ["params.k1.9=-0.07"])
    with pytest.raises(ValueError, match=r"params\.k1\[9\] \(cell 9\).*k1 > max\(k2, 0\)"):
        run_scene(sc, progress=False)


def test_one_cell_override_keeps_the_others_and_round_trips():
    sc = load_scene("default", ["params.sigma.8=0.05"])
    assert sc.params.sigma == (0.072,) * 7 + (0.05,) + (0.072,) * 8
    assert sc.params.varying_keys == ("sigma",) and sc.params.heterogeneous
    t = scene_table(sc)
    assert t["params"]["sigma"] == list(sc.params.sigma)
    again = load_scene("default", ["params.sigma=" + _list(t["params"]["sigma"])])
    assert again.params == sc.params


@pytest.mark.parametrize("model", ["lattice", "hil", "continuum"])
def test_equal_per_cell_values_run_bit_for_bit_as_one_value(model):
    base = ["model=" + model, "t_end_s=1.0"]
    a = run_scene(load_scene("exp3_single_sigma9", base), progress=False)
    b = run_scene(
        load_scene("exp3_single_sigma9", base + ["params.sigma=" + _list(0.072), "params.k1=" + _list(0.06)]),
        progress=False,
    )
    assert np.array_equal(a.alpha, b.alpha) and np.array_equal(a.beta, b.beta)


def test_lattice_forces_use_each_cells_own_law():
    """The per-cell plant's force on cell j equals the force of a uniform plant with cell j's law (same C
    operations: bit for bit), at a state that visits every branch of psi'."""
    rng = np.random.default_rng(1)
    n = 6
    p = Params(
        cells=n,
        sigma=tuple(rng.uniform(0.02, 0.12, n)),
        k_ab=tuple(rng.uniform(0.01, 0.05, n)),
        k1=tuple(rng.uniform(0.05, 0.1, n)),
        k2=tuple(rng.uniform(-0.1, -0.01, n)),
        alpha_star=tuple(rng.uniform(0.5, 1.5, n)),
    )
    x = rng.uniform(-2.5, 2.5, 2 * n)
    opts = ModelOptions(bands="linear")
    f, _ = make_model("lattice", p, [], opts).forces(0.0, x)
    for j in range(1, n + 1):
        fj, _ = make_model("lattice", p.cell(j), [], opts).forces(0.0, x)
        assert f[j - 1] == fj[j - 1] and f[n + j - 1] == fj[n + j - 1]
    # and the Python law agrees per cell
    ra, rb = physics.reaction(p, x[:n], x[n:])
    for j in range(1, n + 1):
        want = physics.reaction(p.cell(j), x[j - 1], x[n + j - 1])
        assert ra[j - 1] == pytest.approx(want[0], abs=1e-15) and rb[j - 1] == pytest.approx(want[1], abs=1e-15)


def test_each_hil_cell_runs_its_own_firmware_law(fw):
    ffi, lib = fw
    sig = [0.04 + 0.005 * j for j in range(16)]
    sc = load_scene("default", ["params.sigma=" + _list(sig)])
    from host_emulator.controller import build_solver

    s = build_solver(sc)
    for j in range(16):
        want = ffi.new("mc_reaction_t *")
        phys = ffi.new("mc_reaction_phys_t *", s.model.cell_phys[0][0])
        phys.sigma_unm = round(sig[j] * 1e6)
        assert lib.mc_reaction_from_phys(want, phys) == lib.MC_OK
        assert s.cells[j].law.g_sigma == want.g_sigma
    assert len({s.cells[j].law.g_sigma for j in range(16)}) == 16


def test_a_heterogeneous_scene_changes_the_pattern_where_its_cells_differ():
    """Cells 9-16 stable on their own: a push on cell 4 patterns cells 1-8 and leaves the far half near rest."""
    sets = [
        "model=lattice",
        "perturbation.1.cell=4",
        "params.k2=" + _list([-0.06] * 8 + [0.03] * 8),
        "params.sigma=" + _list([0.072] * 8 + [0.0] * 8),
    ]
    r = run_scene(load_scene("exp3_single_sigma9", sets), progress=False)
    far = np.abs(r.alpha[-1, 11:]).max()
    near = np.abs(r.alpha[-1, :6]).max()
    assert near > 0.4 and far < 0.1, (near, far)
