"""The instruction-count script: a real callgrind count of a small hil scene (when valgrind is installed), the
figure's arithmetic, and clear errors for what it cannot count."""

from __future__ import annotations

import pytest

from host_emulator.benchmarks import instructions as ins


def test_marginal_is_the_difference_over_the_cell_ticks(monkeypatch, tmp_path):
    """The figure is (count at t1 - count at t0) / ((t1 - t0) rate cells), the groups likewise."""
    totals = {
        0.5: (1_000_000, {"firmware (lib/metacell)": 400_000}),
        1.5: (9_000_000, {"firmware (lib/metacell)": 2_000_000}),
    }
    monkeypatch.setattr(ins, "have_valgrind", lambda: True)
    monkeypatch.setattr(ins, "count", lambda scene, sets, t, wd: ins.Count(t, totals[t][0], totals[t][1]))
    m = ins.measure("default", ["cells=4", "perturbation.1.cell=2"], 0.5, 1.5)
    assert m.cell_ticks == 2000 * 4
    assert m.per_cell_tick == pytest.approx(8_000_000 / 8000)
    assert m.by_group["firmware (lib/metacell)"] == pytest.approx(1_600_000 / 8000)
    assert ins.report(m).splitlines()[-1] == "instructions per cell-tick: 1000"


def test_refuses_what_it_cannot_count(monkeypatch, capsys):
    assert ins.main(["exp3_single_sigma9"]) == 2  # a lattice scene has no control tick
    assert "hil figure" in capsys.readouterr().err
    assert ins.main(["default", "--t0", "2", "--t1", "1"]) == 2
    monkeypatch.setattr(ins.shutil, "which", lambda name: None)
    assert ins.main(["default"]) == 3
    assert "valgrind is not installed" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.skipif(not ins.have_valgrind(), reason="valgrind is not installed")
def test_counts_a_small_scene_under_callgrind(tmp_path):
    """4 cells, 0.05 s to 0.15 s: a count per cell-tick of the order of the default scene's (the firmware tick
    alone is ~150 x86 instructions), repeatable to a few instructions."""
    a = ins.measure("default", ["cells=4", "perturbation.1.cell=2"], 0.05, 0.15)
    assert a.cell_ticks == 200 * 4
    assert 150 < a.per_cell_tick < 2000
    assert a.by_group.get("firmware (lib/metacell)", 0) > 80


def test_bench_speed_names_its_machine_and_the_missing_count(monkeypatch, capsys):
    """bench-speed prints the machine (CPU, cores, load, date) beside its times, and says why the instruction count
    is absent when valgrind is (its return code depends on the machine's speed, so it is not asserted)."""
    import os

    from host_emulator.benchmarks.speed import bench_main

    monkeypatch.setattr(ins.shutil, "which", lambda name: None)
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    try:
        bench_main(["default", "--repeat", "1", "--set", "t_end_s=0.1"])
        out = capsys.readouterr().out
        bench_main(["default", "--repeat", "1", "--set", "t_end_s=0.1", "--no-instructions"])
        out2 = capsys.readouterr().out
    finally:
        if cpus is not None:
            os.sched_setaffinity(0, cpus)  # bench-speed pins its process to one core
    assert "machine: " in out and " cores, load " in out
    assert "instructions per cell-tick: not counted (valgrind is not installed)" in out
    assert "instructions per cell-tick" not in out2
