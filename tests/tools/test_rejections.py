"""Every rejection is one line, exit 2, nothing left behind (issue 32, item 9): unreadable or foreign captures given
to `experiment compare`, a --scheduler that is no address or no Dask scheduler (sweep and design), fault times and
boards the boards cannot take, a --limit that is no fraction, over-long and duplicate design targets, a bad --do of
the logger. Each case runs the command as a user does and checks its stderr is a single line without a traceback,
its exit status 2, and the output path it was given absent afterwards (no empty directory either)."""

import random
import socket
import subprocess
import sys
import threading
from pathlib import Path

import can
import pytest

from metacell_tools.rigtools import logger as L

ROOT = Path(__file__).resolve().parents[2]
FAULT = ["--set", "model=image", "--set", "fault.1.start_s=1"]


@pytest.fixture(scope="module")
def junk_port():
    """A TCP service that is not Dask: it greets as an SSH server does, then waits for the client to go."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)

    def serve():
        while True:
            try:
                c, _ = srv.accept()
            except OSError:
                return
            try:
                c.sendall(b"SSH-2.0-OpenSSH_9.6\r\n")
                c.recv(100)
            except OSError:
                pass
            c.close()

    threading.Thread(target=serve, daemon=True).start()
    yield srv.getsockname()[1]
    srv.close()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    (d / "empty.blf").write_bytes(b"")
    w = can.BLFWriter(str(d / "good.blf"))
    for i in range(3000):
        w.on_message_received(can.Message(timestamp=1000 + i * 1e-3, arbitration_id=0x100 + i % 16, data=bytes(8)))
    w.stop()
    data = bytearray((d / "good.blf").read_bytes())
    for i in range(200, len(data), 97):
        data[i] ^= 0x5A
    (d / "corrupt.blf").write_bytes(bytes(data))
    (d / "garbled.csv").write_text(L.CSV_HEADER + "0,1,1,0.1,5,abc,3,0\n")
    rows = "".join(f"0,{k},{j},{k * 0.01 + j * 5e-4:.6f},1000,10,-5,0\n" for k in range(5) for j in range(1, 17))
    (d / "good.csv").write_text(L.CSV_HEADER + rows)
    (d / "c77.csv").write_text(L.CSV_HEADER + rows + "0,5,77,0.06,1000.06,1,1,0\n")
    rnd = random.Random(1)
    w = can.ASCWriter(str(d / "random.asc"))
    for i in range(20_000):
        w.on_message_received(
            can.Message(
                timestamp=1000 + i * 1e-3,
                arbitration_id=rnd.randrange(0x800),
                is_extended_id=False,
                data=bytes(rnd.randrange(256) for _ in range(8)),
            )
        )
    w.stop()
    return d


def _walls(n):
    return "walls=" + ",".join(f"{1 + i % 15}.5" for i in range(n))


# (id, module, argv with {in} = the inputs, {out} = the output path, {junk} = the non-Dask port; a needle of the line)
CASES = [
    ("compare-empty-blf", "metacell_tools.experiment", ["compare", "{in}/empty.blf", "{in}/good.csv"], "struct.error"),
    ("compare-garbled-csv", "metacell_tools.experiment", ["compare", "{in}/garbled.csv", "{in}/good.csv"], "abc"),
    ("compare-corrupt-blf", "metacell_tools.experiment", ["compare", "{in}/corrupt.blf", "{in}/good.csv"], "zlib"),
    ("compare-random-asc", "metacell_tools.experiment", ["compare", "{in}/random.asc", "{in}/good.csv"], "protocol"),
    ("compare-cell-77", "metacell_tools.experiment", ["compare", "{in}/c77.csv", "{in}/good.csv"], "cell 77"),
    ("sweep-scheduler-bogus", "host_emulator", ["sweep", "default", "--quiet", "--grid", "params.sigma=0.05",
                                                 "--scheduler", "bogus"], "tcp://HOST:PORT"),
    ("design-scheduler-bogus", "host_emulator", ["design", "--target", "lambda=10", "--push", "8", "--quiet",
                                                  "--scheduler", "bogus"], "tcp://HOST:PORT"),
    ("sweep-scheduler-not-dask", "host_emulator", ["sweep", "default", "--quiet", "--grid", "params.sigma=0.05",
                                                    "--scheduler", "tcp://127.0.0.1:{junk}"], "not as a Dask"),
    ("design-scheduler-not-dask", "host_emulator", ["design", "--target", "lambda=10", "--push", "8", "--quiet",
                                                     "--scheduler", "127.0.0.1:{junk}"], "not as a Dask"),
    ("fault-start-1e15", "host_emulator", ["run", "default", "--quiet", "--no-plots", "--set", "model=image",
                                            "--set", "fault.1.kind=hardfault", "--set", "fault.1.cell=2",
                                            "--set", "fault.1.start_s=1e15"], "fault[1].start_s"),
    ("fault-start-1e300", "host_emulator", ["run", "default", "--quiet", "--no-plots", "--set", "model=image",
                                             "--set", "fault.1.kind=hardfault", "--set", "fault.1.cell=2",
                                             "--set", "fault.1.start_s=1e300"], "fault[1].start_s"),
    ("fault-duration-1e300", "host_emulator", ["run", "default", "--quiet", "--no-plots", *FAULT,
                                                "--set", "fault.1.kind=silent", "--set", "fault.1.cell=2",
                                                "--set", "fault.1.duration_s=1e300"], "fault[1].duration_s"),
    ("fault-board-superscript", "host_emulator", ["run", "default", "--quiet", "--no-plots", *FAULT,
                                                   "--set", "fault.1.kind=hardfault",
                                                   "--set", 'fault.1.board="cell\u00b2"'], "fault[1].board"),
    ("fault-board-leading-zeros", "host_emulator", ["run", "default", "--quiet", "--no-plots", *FAULT,
                                                     "--set", "fault.1.kind=hardfault",
                                                     "--set", 'fault.1.board="cell007"'], "fault[1].board"),
    ("cpu-budget-limit-nan", "metacell_tools.fwcheck", ["cpu-budget", "--limit", "nan"], "--limit nan"),
    ("design-3000-walls", "host_emulator", ["design", "--target", _walls(3000), "--push", "8"], "characters"),
    ("design-duplicate-walls", "host_emulator", ["design", "--target", "walls=5.5,5.5", "--push", "8"], "twice"),
    ("logger-bad-do", "metacell_tools.rigtools.logger", ["-c", "/dev/nonexistent@115200", "--do", "1:nonsense",
                                                          "-o", "{out}/run"], "invalid choice"),
]  # fmt: skip
OUT_OPTION = {"host_emulator": ["--out", "{out}"], "metacell_tools.experiment": ["--out", "{out}/cmp.png"]}


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_every_rejection_is_one_line_exit_2_and_leaves_nothing(case, files, junk_port, tmp_path):
    name, module, argv, needle = case
    out = tmp_path / "new" / "out"  # neither exists: a rejection must not leave them
    argv = argv + OUT_OPTION.get(module, [])
    argv = [a.format(**{"in": files, "out": out, "junk": junk_port}) for a in argv]
    r = subprocess.run([sys.executable, "-m", module, *argv], cwd=ROOT, capture_output=True, text=True, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, (name, r.returncode, r.stderr[-2000:])
    assert len(lines) == 1 and "Traceback" not in r.stderr, (name, r.stderr[-2000:])
    assert needle in lines[0] and len(lines[0]) < 400, (name, lines[0][:500])
    assert not (tmp_path / "new").exists(), (name, sorted(p.name for p in (tmp_path / "new").rglob("*")))
