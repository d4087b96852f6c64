"""The logger never leaves a file its readers cannot open: atomic NPZ, BLF and NPZ repair after a kill, CSV rows on
disk within a bounded time of their frame (heartbeat or not), partial first/last cycles flagged."""

import os
import re
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np
import pytest

from host_emulator.workbench import datasets
from metacell_tools.rigtools import logger as L
from metacell_tools.rigtools import proto

ROOT = proto.ROOT


def _blf(path: Path, n: int, container: int = 4096) -> list[can.Message]:
    msgs = [
        can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100 + i % 16, data=bytes([i % 256] * 8))
        for i in range(n)
    ]
    w = can.BLFWriter(str(path), max_container_size=container)
    for m in msgs:
        w.on_message_received(m)
    w.stop()
    return msgs


def _read_blf(path: Path) -> list[can.Message]:
    return list(can.BLFReader(str(path)))


@pytest.mark.parametrize("cut", [0, 10, 144, 150, "mid", -3])
def test_repair_blf_cuts_to_the_last_complete_object(tmp_path, cut):
    p = tmp_path / "x.blf"
    msgs = _blf(p, 2000)
    data = p.read_bytes()
    if cut == "mid":
        cut = len(data) // 2
    p.write_bytes(data[:cut] if cut >= 0 else data[:cut])
    changed = L.repair_blf(p)
    assert changed is not None
    got = _read_blf(p)  # python-can reads it now
    assert len(got) <= len(msgs)
    for a, b in zip(got, msgs):  # a prefix of what was written, every frame whole
        assert a.arbitration_id == b.arbitration_id and bytes(a.data) == bytes(b.data)
    if isinstance(cut, int) and cut < 0:
        assert len(got) > 0
    assert L.repair_blf(p) is None  # a sound file is left alone


def test_repair_blf_leaves_a_complete_file_alone(tmp_path):
    p = tmp_path / "x.blf"
    msgs = _blf(p, 500)
    before = p.read_bytes()
    assert L.repair_blf(p) is None
    assert p.read_bytes() == before and len(_read_blf(p)) == len(msgs)


def test_npz_is_written_atomically(tmp_path, monkeypatch):
    """A failing write (full disk) leaves the previous NPZ or none: never a cut or 0-byte file. The one writer of
    the run layout (datasets.save_npz_atomic, under write_npz) is what the logger, the experiment runner's
    per-repeat NPZ, --repair and the run command use."""
    p = tmp_path / "r.npz"
    datasets.save_npz_atomic(p, {"a": np.arange(5)})

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", full)
    with pytest.raises(OSError):
        datasets.save_npz_atomic(p, {"a": np.arange(7)})
    assert list(np.load(p)["a"]) == list(range(5))
    assert not (tmp_path / "r.npz.tmp").exists()
    rows = np.array([(0, k, j, k * 0.01, 0.0, 1, 2, 0) for k in range(3) for j in (1, 2)], dtype=float)
    with pytest.raises(OSError):  # the logger's own NPZ goes the same way
        L.write_capture(p, L.rows_to_arrays(rows, 2, []), {"source": "rig"})
    assert list(np.load(p)["a"]) == list(range(5))
    p.unlink()
    with pytest.raises(OSError):
        datasets.save_npz_atomic(p, {"a": np.arange(7)})
    assert not p.exists() and not (tmp_path / "r.npz.tmp").exists()


def test_rows_reach_the_csv_within_the_bound_without_a_heartbeat(tmp_path):
    """Held rows wait HOLD_S at most (host clock) and the CSV chunk FLUSH_S: no heartbeat, few rows, still on disk."""
    csv = L.CsvChunks(tmp_path / "x.csv")
    dec = L.SampleDecoder(n_cells=2, report=lambda t: None, sink=csv, hold=True)
    t0 = 5000.0
    for k in range(5):
        for j in (1, 2):
            dec.sample(j, k, 10 * k, -k, 70 * k, 0, t0 + k * 0.009)
    assert len(L.read_rows(csv.path)) == 0  # held for a heartbeat, far fewer than a chunk
    dec.tick(t0 + 0.5)
    assert len(dec.held) == 10  # within HOLD_S: still waiting
    dec.tick(t0 + L.SampleDecoder.HOLD_S + 0.05)
    assert not dec.held
    csv.since = time.monotonic() - L.CsvChunks.FLUSH_S  # as if FLUSH_S had passed (no sleeping in tests)
    csv.tick()
    rows = L.read_rows(csv.path)
    assert len(rows) == 10 and list(rows[:, 5][:2]) == [0, 0]


def test_partial_first_and_last_cycles_are_flagged():
    # cells 1..3; the log starts inside cycle 10 (cell 3 only) and stops inside cycle 13 (cells 1, 2);
    # cell 2 misses cycle 12 in the middle: a gap, not a partial cycle
    rows = []
    for k, cells in ((10, [3]), (11, [1, 2, 3]), (12, [1, 3]), (13, [1, 2])):
        rows += [(0, k, j, k * 0.01, 0.0, 1, 2, 0) for j in cells]
    rows += [(1, 50, j, 1.0, 0.0, 1, 2, 0) for j in (1, 2, 3)]  # a reconnect: a whole cycle
    arr = L.rows_to_arrays(np.array(rows, dtype=float), 3, [])
    assert list(arr["cycle"]) == [10, 11, 12, 13, 50]
    assert list(arr["partial"]) == [True, False, False, True, False]
    assert L.gaps_from_rows(np.array(rows, dtype=float)) == [(0, 2, 12, 1)]


def test_partial_cycles_reach_the_run_layout(tmp_path):
    """The flag survives into the one run layout: the logger's NPZ, he.load of it and of the CSV alone (gaps from
    the cycle counters), and an NPZ of the logger's older layout (computed when loaded)."""
    import host_emulator as he

    rows = []
    for k, cells in ((10, [3]), (11, [1, 2, 3]), (12, [1, 3]), (13, [1, 2])):
        rows += [(0, k, j, k * 0.01, 100.0 + k, 1, 2, 0) for j in cells]
    rows_a = np.array(rows, dtype=float)
    arr = L.rows_to_arrays(rows_a, 3, [])
    want = [True, False, False, True]
    prefix = tmp_path / "cap"
    L.write_capture(prefix.with_suffix(".npz"), arr, {"source": "rig"})
    with open(prefix.with_suffix(".csv"), "w") as f:
        f.write(L.CSV_HEADER + L.format_rows(rows))
    with np.load(prefix.with_suffix(".npz")) as z:
        assert str(z["format"]) == datasets.FORMAT and list(z["partial"]) == want
    ds = he.load(prefix.with_suffix(".npz"))
    assert list(ds["partial"].values) == want and ds.attrs["source"] == "rig"
    assert ds.isel(time=~ds["partial"].values).sizes["time"] == 2  # as docs/datapath.md shows
    ds_csv = he.load(prefix.with_suffix(".csv"))
    assert list(ds_csv["partial"].values) == want
    assert ds_csv["gaps"].values.tolist() == [[0, 2, 12, 1]]
    old = {k: v for k, v in arr.items() if k != "partial"}  # a logger NPZ from before the flag
    np.savez_compressed(tmp_path / "old.npz", **old)
    assert list(he.load(tmp_path / "old.npz")["partial"].values) == want


def start_server(link: Path) -> subprocess.Popen:
    p = subprocess.Popen(
        [sys.executable, "-m", "host_emulator", "serve", "exp5_rest", "--duration", "300", "--link", str(link)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = p.stdout.readline()
    assert re.match(r"slcan pty: (\S+)", first), (first, p.stderr.read() if p.poll() is not None else "")
    return p


def wait_for(pred, timeout: float, what: str):
    """Poll pred() until true; generous timeouts (the machine may be loaded), a clear message otherwise."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")


@pytest.mark.slow
def test_a_killed_logger_leaves_files_every_reader_opens(tmp_path):
    """SIGKILL mid-run: pandas reads the CSV, python-can the ASC and (after --repair) the BLF, np.load the rebuilt
    NPZ; the sample counts agree within the documented window (HOLD_S + FLUSH_S of rows, 1 s of log buffers)."""
    import pandas as pd

    link, out = tmp_path / "rig", tmp_path / "k"
    srv = start_server(link)
    try:
        lg = subprocess.Popen(
            [sys.executable, "-m", "metacell_tools.rigtools.logger", "-c", f"{link}@115200", "-o", str(out)]
            + ["--formats", "asc,blf", "--duration", "600"],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        csv = out.with_suffix(".csv")
        try:
            wait_for(lambda: csv.exists() and csv.stat().st_size > 400_000, 240, "6,000 CSV rows from the logger")
        finally:
            lg.send_signal(signal.SIGKILL)
            lg.wait(30)
    finally:
        srv.send_signal(signal.SIGTERM)
        srv.wait(30)
    df = pd.read_csv(csv)  # a cut last line is tolerated by no reader: the logger writes whole lines
    assert list(df.columns) == L.CSV_HEADER.strip().split(",") and len(df) > 5000
    asc = [
        m for m in can.ASCReader(str(out.with_suffix(".asc"))) if proto.frame_kind(m.arbitration_id)[0] == "CELL_SAMPLE"
    ]
    r = subprocess.run(
        [sys.executable, "-m", "metacell_tools.rigtools.logger", "--repair", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    blf = [
        m for m in can.BLFReader(str(out.with_suffix(".blf"))) if proto.frame_kind(m.arbitration_id)[0] == "CELL_SAMPLE"
    ]
    arr = np.load(out.with_suffix(".npz"))
    n_npz = int(np.sum(~np.isnan(arr["alpha_counts"])))
    assert n_npz == len(df)
    import host_emulator as he

    ds = he.load(out.with_suffix(".npz"))  # the rebuilt NPZ is the run layout, labelled as the CSV allows
    assert ds.attrs["format"] == datasets.FORMAT and ds.attrs["source"] == "unknown"
    assert int(np.isfinite(ds["alpha"].values).sum()) == len(df) and ds["partial"].dtype == bool
    span = asc[-1].timestamp - asc[0].timestamp
    rate = len(asc) / span
    window = (L.SampleDecoder.HOLD_S + L.CsvChunks.FLUSH_S + L.RigLogger.WRITERS_FLUSH_S + 0.5) * rate
    counts = {"csv": len(df), "asc": len(asc), "blf": len(blf)}
    assert max(counts.values()) - min(counts.values()) <= window, (counts, window)


def test_full_disk_leaves_no_empty_npz(tmp_path):
    """The NPZ of a run whose disk fills is complete or absent, and --repair rebuilds it once there is room."""
    import resource

    link, out = tmp_path / "rig", tmp_path / "full"
    srv = start_server(link)
    try:

        def limit():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

        r = subprocess.run(
            [sys.executable, "-m", "metacell_tools.rigtools.logger", "-c", f"{link}@115200", "-o", str(out)]
            + ["--formats", "asc,blf", "--duration", "600"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
            preexec_fn=limit,
        )
    finally:
        srv.send_signal(signal.SIGTERM)
        srv.wait(30)
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    npz = out.with_suffix(".npz")
    if npz.exists():
        assert npz.stat().st_size > 0
        np.load(npz)["alpha_counts"]
    list(can.BLFReader(str(out.with_suffix(".blf"))))  # cut to its last whole object by the logger itself
    arr = L.repair(out, report=lambda t: None)
    assert np.sum(~np.isnan(arr["alpha_counts"])) == len(L.read_rows(out.with_suffix(".csv")))
    assert np.load(npz)["alpha_counts"].shape == arr["alpha_counts"].shape


def test_blf_header_constant_matches_python_can():
    from can.io.blf import FILE_HEADER_SIZE, OBJ_HEADER_BASE_STRUCT

    assert L.BLF_HEADER == FILE_HEADER_SIZE and L.BLF_OBJ.format == OBJ_HEADER_BASE_STRUCT.format
    assert struct.calcsize(L.BLF_OBJ.format) == 16
    assert os.path.exists(can.io.blf.__file__)
