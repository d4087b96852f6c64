"""Rig logger under stalls, signals, write errors and bad input: time and cycles never go backwards or overwrite, files
stay readable."""

import resource
import signal
import struct
import subprocess
import sys

import can
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from metacell_tools.rigtools import proto
from metacell_tools.rigtools.logger import SampleDecoder, read_rows, rows_to_arrays, truncate_to_last_line

ROOT = proto.ROOT
SAMPLE = proto.FRAMES["CELL_SAMPLE"]["base"]
HB = proto.FRAMES["PRIMARY_STATUS"]["base"]


def primary_stream(n_cycles, period_us, drop, n_cells=3, slot_us=500, hb_every_us=1_000_000, backlog=50):
    """Frames as the primary emits them (samples, heartbeats) with cycles in `drop` lost; truth per sample.

    Host timestamps: read promptly, except the `backlog` cycles before the lost ones, which a
    stalled reader reads only when it resumes (with the first frames after the gap)."""
    out, truth = [], []
    k0 = min(drop) if drop else n_cycles
    backlog = min(backlog, k0 // 2)  # the segment's first frames are read promptly
    resume = (max(drop) + 1) * period_us * 1e-6 if drop else 0.0
    next_hb = hb_every_us

    def host(k, t):
        return 1000.0 + (resume if k0 - backlog <= k < k0 else t * 1e-6) + 0.002

    for k in range(n_cycles):
        for j in range(1, n_cells + 1):
            t = k * period_us + j * slot_us
            while t >= next_hb:  # a heartbeat in a lost cycle is lost with it
                if k not in drop and t - next_hb < period_us:
                    out.append(
                        can.Message(
                            arbitration_id=HB,
                            is_extended_id=False,
                            timestamp=host(k, t),
                            data=struct.pack("<IHBB", next_hb // 1000, 100, 0, 0),
                        )
                    )
                next_hb += hb_every_us
            if k in drop:
                continue
            out.append(
                can.Message(
                    arbitration_id=SAMPLE + j,
                    is_extended_id=False,
                    timestamp=host(k, t),
                    data=struct.pack("<BhhHB", k & 0xFF, k % 1000, -j, (t >> 7) & 0xFFFF, 0),
                )
            )
            truth.append((k, j, t))
    return out, truth


@settings(max_examples=150, deadline=None)
@given(
    st.integers(5, 400),
    st.integers(1, 9000),
    st.integers(50, 400),
    st.sampled_from([2000, 9000, 12345]),
    st.integers(0, 300),
)
def test_any_stall_length_keeps_time_and_cycles_in_order(k0, length, after, period_us, backlog):
    """Frames lost for 0.002..110 s (far beyond the 8-bit cycle and 16-bit time wraps): every sample keeps
    its true cycle and time, gaps report exactly the lost cycles, nothing is overwritten."""
    drop = set(range(k0, k0 + length))
    msgs, truth = primary_stream(k0 + length + after, period_us, drop, backlog=backlog)
    dec = SampleDecoder(n_cells=3, report=lambda t: None, hold=True)
    for m in msgs:
        dec.feed(m)
    dec.finish()
    rows = np.array(dec.rows, dtype=float)
    assert len(rows) == len(truth)
    np.testing.assert_array_equal(rows[:, 1] - rows[0, 1], [k for k, _, _ in truth])
    t_true = np.array([t for _, _, t in truth]) * 1e-6
    np.testing.assert_allclose(rows[:, 3] - rows[0, 3], t_true - t_true[0], atol=2.6e-4)
    assert np.all(np.diff(rows[:, 3]) >= 0)
    assert [(g[1], g[3]) for g in dec.gaps] == [(j, length) for j in (1, 2, 3)]
    arr = rows_to_arrays(rows, 3, dec.gaps)
    assert np.sum(~np.isnan(arr["alpha_counts"])) == len(truth)


def test_truncate_to_last_line(tmp_path):
    p = tmp_path / "x.asc"
    p.write_bytes(b"a\nbb\ncc")
    truncate_to_last_line(p)
    assert p.read_bytes() == b"a\nbb\n"


def run_logger(args, timeout=600, **kw):
    return subprocess.run(
        [sys.executable, "-m", "metacell_tools.rigtools.logger", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        **kw,
    )


def test_logger_bad_input_is_a_one_line_error(tmp_path):
    cases = [
        (["-c", "x", "-o", str(tmp_path / "a"), "--duration", "nan"], 2),
        (["-c", "x", "-o", str(tmp_path / "a"), "--duration", "-1"], 2),
        (["-c", "x", "-o", str(tmp_path / "a"), "--do", "1:perturb 8 --torque inf --duration 0.1"], 2),
        (["-c", "x", "-o", str(tmp_path / "a"), "--formats", "xyz"], 2),
        (["-c", "x", "-o", "/proc/nope/run"], 2),
        (["-c", "/dev/nonexistent-port@115200", "-o", str(tmp_path / "a"), "--duration", "1"], 3),
    ]
    (tmp_path / "f").write_text("")
    cases.append((["-c", "x", "-o", str(tmp_path / "f" / "run")], 2))
    for args, code in cases:
        r = run_logger(args)
        assert r.returncode == code, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr, (args, r.stderr)


def test_command_tool_bad_values_and_missing_port():
    from metacell_tools.rigtools import command

    assert command.main(["-c", "x", "perturb", "8", "--torque", "inf", "--duration", "0.1"]) == 2
    assert command.main(["-c", "x", "set", "3", "sigma", "1e9"]) == 2
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "metacell_tools.rigtools.command",
            "-c",
            "/dev/nonexistent-port@115200",
            "enable",
            "3",
            "on",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 3 and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_full_disk_ends_with_one_line_and_readable_files(tmp_path):
    """A file size limit stands in for a full disk: exit 3, one line, ASC and CSV readable to the last record."""
    import re

    link = tmp_path / "rig"
    srv = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "host_emulator",
            "serve",
            "exp5_rest",
            "--slcan",
            "--duration",
            "1200",  # stopped at the end of the test; long enough for a loaded machine
            "--link",
            str(link),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert re.match(r"slcan pty: (\S+)", srv.stdout.readline())

        def limit():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))

        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "metacell_tools.rigtools.logger",
                "-c",
                f"{link}@115200",
                "-o",
                str(tmp_path / "full"),
                "--formats",
                "asc",
                "--duration",
                "600",
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,  # generous: a loaded machine; the write error ends it long before --duration
            preexec_fn=limit,
        )
    finally:
        srv.terminate()
        srv.wait(60)
    assert r.returncode == 3, r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("logger: write failed") and "Traceback" not in r.stderr, r.stderr
    asc = tmp_path / "full.asc"
    assert asc.read_bytes().endswith(b"\n")
    n = sum(1 for _ in can.ASCReader(str(asc)))
    assert n > 1000
    rows = read_rows(tmp_path / "full.csv")
    assert len(rows) > 1000
