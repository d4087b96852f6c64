"""Foreign data is refused, never taken as ours: a python-can log of another protocol's frames (unknown CAN IDs,
or this protocol's IDs with times that run backwards once decoded) and logger CSV rows naming cells the rig has not
are each a LoadError of one line from he.load, and `experiment compare` says so in one line, exit 2, no figure;
every unreadable input (an empty or corrupted BLF, a garbled CSV, a NetCDF that is none) is a LoadError too. A
genuine capture, stalls and all, still loads."""

import random
import subprocess
import sys

import can
import numpy as np
import pytest

from host_emulator.workbench.datasets import FOREIGN_MAX, LoadError, load
from metacell_tools.rigtools import logger as L
from metacell_tools.rigtools import proto
from tests.tools.test_logger_robust import primary_stream

ROOT = proto.ROOT


def _asc(path, msgs):
    w = can.ASCWriter(str(path))
    for m in msgs:
        w.on_message_received(m)
    w.stop()
    return path


def _random_frames(n, ids, seed=1):
    rnd = random.Random(seed)
    return [
        can.Message(
            timestamp=1000 + i * 1e-3,
            arbitration_id=rnd.choice(ids),
            is_extended_id=False,
            data=bytes(rnd.randrange(256) for _ in range(8)),
        )
        for i in range(n)
    ]


def _genuine(n_cycles=400):
    msgs, truth = primary_stream(n_cycles, 9000, set(range(150, 1200)), n_cells=16)  # a 9.5 s stall in it
    return msgs, truth


def _csv(path, extra=""):
    rows = "".join(
        f"0,{k},{j},{k * 0.01 + j * 5e-4:.6f},{1000 + k * 0.01:.6f},10,-5,0\n" for k in range(5) for j in range(1, 17)
    )
    path.write_text(L.CSV_HEADER + rows + extra)
    return path


def compare(a, b, out):
    return subprocess.run(
        [sys.executable, "-m", "metacell_tools.experiment", "compare", str(a), str(b), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_log_of_random_standard_frames_is_refused(tmp_path):
    """The issue's probe: 20,000 random standard-ID frames loaded as 11 samples, times out of order, and compare
    plotted them with exit 0."""
    f = _asc(tmp_path / "random.asc", _random_frames(20_000, range(0x800)))
    with pytest.raises(LoadError, match=r"frames \(9\d %\) are not this protocol's"):
        load(f)
    png = tmp_path / "cmp.png"
    r = compare(f, f, png)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "not a capture of this rig" in r.stderr and not png.exists()


def test_this_protocols_ids_with_foreign_contents_are_refused(tmp_path):
    """Only CELL_SAMPLE IDs, random payloads: the IDs pass, the decoded times run backwards."""
    ids = [proto.FRAMES["CELL_SAMPLE"]["base"] + j for j in range(1, 17)]
    f = _asc(tmp_path / "samples.asc", _random_frames(3000, ids, seed=2))
    with pytest.raises(LoadError, match="times run backwards"):
        load(f)


def test_a_genuine_capture_loads_with_a_few_foreign_frames(tmp_path):
    msgs, truth = _genuine()
    few = _random_frames(int(FOREIGN_MAX * len(msgs) * 0.8), [0x7F0, 0x123])  # under the limit: kept, ignored
    ds = load(_asc(tmp_path / "ok.asc", sorted(msgs + few, key=lambda m: m.timestamp)))
    assert int(np.isfinite(ds["alpha"].values).sum()) == len(truth)
    assert ds.sizes["cell"] == 16 and np.all(np.diff(ds["time"].values) > 0)
    many = _random_frames(int(FOREIGN_MAX * len(msgs) * 1.5), [0x7F0, 0x123])
    with pytest.raises(LoadError, match="not this protocol's"):
        load(_asc(tmp_path / "mixed.asc", sorted(msgs + many, key=lambda m: m.timestamp)))


def test_a_csv_row_naming_a_cell_outside_the_rig_is_refused(tmp_path):
    """The issue's probe: one stray row with cell 77 made he.load return a 77-cell dataset."""
    assert load(_csv(tmp_path / "good.csv")).sizes["cell"] == 16
    with pytest.raises(LoadError, match=r"data row 81: cell 77, expected a whole number in 1\.\.16"):
        load(_csv(tmp_path / "c77.csv", "0,5,77,0.06,1000.06,1,1,0\n"))
    with pytest.raises(LoadError, match="times run backwards"):
        load(_csv(tmp_path / "back.csv", "0,5,3,0.001,1000.06,1,1,0\n"))
    r = compare(tmp_path / "c77.csv", tmp_path / "good.csv", tmp_path / "cmp.png")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "cell 77" in r.stderr, r.stderr


def _blf(path):
    w = can.BLFWriter(str(path))
    for m in _genuine(60)[0]:
        w.on_message_received(m)
    w.stop()
    return path


BAD = {
    "empty.blf": lambda p: p.write_bytes(b""),
    "corrupt.blf": lambda p: p.write_bytes(
        bytes(b ^ 0x5A if i > 200 and i % 97 == 0 else b for i, b in enumerate(_blf(p).read_bytes()))
    ),
    "garbled.csv": lambda p: p.write_text(L.CSV_HEADER + "0,1,1,0.1,5,abc,3,0\n"),
    "short.csv": lambda p: p.write_text(L.CSV_HEADER + "0,1,1,0.1\n"),
    "binary.csv": lambda p: p.write_bytes(bytes(range(256)) * 4),
    "bogus.nc": lambda p: p.write_bytes(b"CDF\x01" + bytes(60)),
    "noise.nc": lambda p: p.write_bytes(bytes(range(256)) * 4),
    "bogus.asc": lambda p: p.write_bytes(bytes(range(256)) * 4),
}


@pytest.mark.parametrize("name", list(BAD))
def test_every_unreadable_input_is_a_load_error(tmp_path, name):
    p = tmp_path / name
    BAD[name](p)
    with pytest.raises(LoadError) as e:
        load(p)
    text = str(e.value)
    assert text.startswith(str(p)) and "\n" not in text and len(text) < 400, text


@pytest.mark.parametrize(
    "summary",
    [[1, 2], "x", {"scene": "default", "per_repeat": [1, 2]}, {"scene": "default", "per_repeat": [{"x": 1}]}],
    ids=["list", "string", "repeats-not-tables", "repeat-without-number"],
)
def test_a_run_directory_with_a_foreign_summary_is_a_load_error(tmp_path, summary):
    import json

    (tmp_path / "summary.json").write_text(json.dumps(summary))
    for repeat in (None, 1):
        with pytest.raises(LoadError) as e:
            load(tmp_path, repeat=repeat)
        assert str(e.value).startswith(str(tmp_path)) and "\n" not in str(e.value), str(e.value)
