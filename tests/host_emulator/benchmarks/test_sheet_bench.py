"""The sheet benchmark runs both models on a sheet and a chain and prints one row each (no timing asserted)."""

from __future__ import annotations

import math

from host_emulator.benchmarks import sheet


def test_sheet_benchmark_rows():
    n, ns, sub = sheet.cost("hil", (4, 4), "square", "periodic", steps=2)
    assert n == 16 and math.isfinite(ns) and ns > 0 and sub >= 1
    out = sheet.sheets(sides=(4,), log=lambda *a: None)
    lines = out.splitlines()
    assert len(lines) == 2 + 4
    assert "4 x 4 periodic" in out and "16 cells" in out and "cell-tick" in out and "cell-step" in out
