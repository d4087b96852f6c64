"""The issue's small things: design says its landing fraction is per generation (with the best so far), its figure's
legends leave every cell clear, a one-parameter sweep's regime map has no seed axis, and a sweep's local Dask
cluster does not warn when something else (a notebook's dashboard) holds port 8787."""

import re
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from host_emulator.params import Params
from host_emulator.workbench.design.plot import plot_design
from host_emulator.workbench.design.search import hil_search
from host_emulator.workbench.design.space import space_for
from host_emulator.workbench.design.target import parse_pushes, parse_target

ROOT = Path(__file__).resolve().parents[3]


def _kinks(walls, n=16):
    j = np.arange(1, n + 1, dtype=float)
    u = np.full(n, 0.6)
    for w in walls:
        u = u * np.tanh((w - j) / 0.6)
    return u


def test_design_search_reports_each_generations_best_and_the_best_so_far():
    target = parse_target("lambda=10")
    space = space_for(Params(), ["sigma"], (), target)
    rng = np.random.default_rng(3)
    landed = _kinks([3.5, 8.5, 13.5])

    def runner(tables):  # a stand-in for the hil ensembles: each run lands with a probability of its own
        p = rng.uniform(0, 0.6)
        return [
            {"final_alpha": landed if rng.uniform() < p else np.zeros(16), "final_beta": np.zeros(16), "steady": True}
            for _ in tables
        ]

    lines: list[str] = []
    from host_emulator.scene import load_scene, scene_table

    base = scene_table(load_scene("default"))
    hil_search(
        space, target, parse_pushes("8"), base, space.x0(), runner, seeds=2, maxiter=2, popsize=5, report=lines.append
    )
    pat = re.compile(
        r"hil search, (first guess|generation (\d+)): (\d+) candidate\(s\) x 6 runs; best of these lands in "
        r"([\d.]+) of its runs \(best so far ([\d.]+)\)"
    )
    got = [pat.fullmatch(ln) for ln in lines]
    assert all(got), lines
    assert got[0].group(1) == "first guess" and [int(m.group(2)) for m in got[1:]] == list(range(1, len(got)))
    tops = [float(m.group(4)) for m in got]
    assert [float(m.group(5)) for m in got] == pytest.approx(list(np.maximum.accumulate(tops)), abs=1e-3)
    assert len(set(tops)) > 1  # the per-generation figure moves; the best so far never falls


def test_design_figures_legends_leave_every_cell_clear(tmp_path):
    target = parse_target("walls=5.5,10.5")
    prof = _kinks([5.5, 10.5])
    doc = {
        "verification": {
            "runs": [{"final_alpha_rad": list(prof * s), "landed": s > 0.9} for s in (1.0, 0.95, 0.5)],
            "fraction_seeds": 0.67,
            "seeds": 3,
            "fraction_pushes": 1.0,
        },
        "linear_theory": {"mode_alpha": list(prof / 0.6)},
        "push_text": "8",
        "vary": ["sigma", "k_ab", "k2"],
        "params": {"sigma": [0.07] * 8 + [0.08] * 8, "k_ab": 0.02, "k2": -0.06},
        "pushes": [{"cell": 8}],
    }
    fig = plot_design(doc, target, tmp_path / "design.png")
    assert (tmp_path / "design.png").stat().st_size > 10_000
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    for ax in fig.axes:
        leg = ax.get_legend()
        assert leg is not None
        box, area = leg.get_window_extent(renderer), ax.get_window_extent(renderer)
        assert box.x0 >= area.x1 - 1 or not box.overlaps(area), (box, area)
        assert box.x1 <= fig.bbox.x1 + 1  # and inside the figure


def test_a_one_parameter_sweeps_regime_map_pools_the_seeds(tmp_path):
    from host_emulator.workbench.sweep import sweep

    out = tmp_path / "sw"
    ds = sweep(
        "default",
        {"params.sigma": [0.05, 0.09]},
        seeds=2,
        out=out,
        fixed=["t_end_s=0.3"],
        workers=1,
        progress=False,
        plots=False,
    )
    from host_emulator.workbench.sweep.figures import plot_regime_map

    fig = plot_regime_map(ds, "sigma")
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["all 2 seed(s)"]
    assert ax.get_ylabel() == "" and ax.get_xlabel() == "params.sigma"
    assert ax.images[0].get_array().shape == (1, 2)
    # the command's figures: the map over sigma alone, never sigma x seed
    from host_emulator.workbench.sweep import driver

    seen = []
    real = driver.plot_regime_map
    driver.plot_regime_map = lambda ds, *keys, **kw: seen.append(keys) or real(ds, *keys, **kw)
    try:
        sweep("default", {"params.sigma": [0.05, 0.09]}, seeds=2, out=out, fixed=["t_end_s=0.3"], progress=False)
    finally:
        driver.plot_regime_map = real
    assert seen == [("sigma",)] and (out / "regime_map.png").exists()


def test_a_sweep_does_not_warn_when_port_8787_is_taken(tmp_path):
    """A notebook with its own Dask dashboard holds 8787; the sweep's cluster serves nothing there."""
    script = textwrap.dedent(
        f"""
        import socket, warnings
        if __name__ == "__main__":
            s = socket.socket(); s.bind(("127.0.0.1", 8787)); s.listen()
            import host_emulator as he
            with warnings.catch_warnings(record=True) as w:
                warnings.simplefilter("always")
                he.sweep("default", {{"params.sigma": [0.05]}}, fixed={{"t_end_s": 0.2}}, out={str(tmp_path / "o")!r},
                         workers=1, progress=False, plots=False)
            print("WARNINGS:", [str(x.message).splitlines()[0] for x in w if "8787" in str(x.message)])
        """
    )
    probe = socket.socket()
    try:
        probe.bind(("127.0.0.1", 8787))
    except OSError:
        pytest.skip("port 8787 is in use on this machine already")
    finally:
        probe.close()
    f = tmp_path / "s.py"
    f.write_text(script)
    r = subprocess.run(
        [sys.executable, str(f)], cwd=ROOT, capture_output=True, text=True, timeout=600, env={"PYTHONPATH": str(ROOT)}
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert "WARNINGS: []" in r.stdout, r.stdout + r.stderr[-2000:]
    assert "8787" not in r.stderr
