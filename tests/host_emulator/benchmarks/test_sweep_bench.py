"""The sweep benchmark runs end to end on a tiny problem and reports what it measured (no timing asserted)."""

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from host_emulator.benchmarks import sweep as sweep_bench
from host_emulator.workbench.sweep import chunk_size


def test_chunks_follow_the_sweep_rule():
    specs = list(range(400))
    ch = sweep_bench._chunks(specs, 2)
    # 14 tasks: 7 rounds of 2, so neither worker runs a last chunk alone (13 tasks of 32 used to split 7/6)
    assert [len(c) for c in ch] == [29] * 13 + [23] and sum(ch, []) == specs
    assert [len(c) for c in sweep_bench._chunks(list(range(10)), 2)] == [2] * 5  # ceil(10 / 8) = 2


@given(st.integers(1, 5000), st.integers(1, 8))
def test_chunk_size_bounds(points, workers):
    size = chunk_size(points, workers)
    tasks = math.ceil(points / size)
    assert 1 <= size <= 32
    assert size <= math.ceil(points / (4 * workers))  # a task is at most a quarter of a worker's even share
    # the busiest worker does at most one chunk more than an even share
    assert math.ceil(tasks / workers) * size <= points / workers + size


@pytest.mark.slow
def test_measure_and_report_tiny(tmp_path, capsys):
    out = tmp_path / "b.json"
    png = tmp_path / "b.png"
    rc = sweep_bench.main(
        ["--points", "4", "--workers", "1", "--t-end", "0.2", "--repeat", "1", "--big", "10", "--json", str(out),
         "--plot", str(png)]
    )  # fmt: skip
    assert rc == 0
    text = capsys.readouterr().out
    r = json.loads(out.read_text())
    assert r["points"] == 4 and r["big_points"] == 10 and set(r["rates"]) == {"1"} and set(r["baseline_rates"]) == {"1"}
    assert all(v > 0 for v in r["rates"]["1"]["runs"] + r["point_s"]["runs"] + r["task_overhead_s"]["runs"])
    assert "1 worker(s), 4 points" in text and "10-point sweep" in text and png.stat().st_size > 0
    assert r["provenance"]["command"]
    with pytest.raises(SystemExit):
        sweep_bench.main(["--points", "0"])
