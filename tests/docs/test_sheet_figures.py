"""docs/hardware.md's sheet table: the I2C bounds per cell count are what the timing model computes (the emulated
columns are `python -m host_emulator.benchmarks.bus --cells 16 32 64`'s; tests/firmware/test_bus_sheet.py holds the
emulated rate within 10 % of the bound); and the cell numbering it draws is topology.py's."""

import re
from pathlib import Path

from host_emulator.bus.i2c import I2CTiming, lattice_rate_limit
from host_emulator.topology import Topology

HW = (Path(__file__).resolve().parents[2] / "docs" / "hardware.md").read_text()


def test_the_sheet_table_quotes_the_bus_bounds():
    read = I2CTiming(400_000).transaction_s(23)
    assert "= 546.3 µs, so a cycle" in HW and round(read * 1e6, 1) == 546.3
    slow = 218 * (2.5e-6 + 300e-9) + 1.3e-6  # every bit 2.5 us + t_r at the Fast-mode limit
    assert f"at t_r = 300 ns a read\ntakes {slow * 1e6:.1f} µs" in HW
    for n in (16, 32, 64):
        bound = lattice_rate_limit(400_000, cells=n)
        row = f"| {n} | {bound:.2f} | {1e3 / bound:.2f} ms |"
        assert row in HW, row
        assert f"| {1 / (n * slow):.1f} Hz |" in HW


def test_the_drawn_numbering_is_the_topology_s():
    t = Topology.from_spec([4, 4])
    rows = [" ".join(str(t.cell_of(r, c)) for c in range(1, 5)) for r in range(1, 5)]
    drawn = re.findall(r"row \d +(\d+) =+ +(\d+) =+ +(\d+) =+ +(\d+)", HW)
    assert [" ".join(d) for d in drawn] == rows
    assert len(t.bonds) == 24 and sorted(t.degree().tolist()).count(4) == 4
    assert f"{len(Topology.from_spec([4, 4], 'hex').bonds)} bonds instead of 24" in HW
