"""Machine-independent cost of the image tier: x86 instructions per board second of the default scene, by callgrind.

    python -m host_emulator.benchmarks.image_instructions                     # default and default-untimed, 0.1 s
    python -m host_emulator.benchmarks.image_instructions --case default --seconds 0.2 --top 12
    python -m host_emulator.benchmarks.image_instructions --case full-speed --top 12

Each case runs in a fresh Python process under ``valgrind --tool=callgrind --instr-atstart=no``: the world is
built and brought up (boot, USB, the cells configured) uninstrumented, then this process switches callgrind's
instrumentation on (``callgrind_control -i on PID``) for `seconds` of board time of the scene and off again, so
the count is the instructions those board seconds took, the rest of the process excluded. Cases: "default" (the
default scene, model = image), "default-untimed" (the same with model_options.image.fast_forward_timed off:
the primary's polling loops run in full) and "full-speed" (the plant at rest, every encoder at the motors' full
speed: benchmarks/image.py's scenario; only when asked for). All run
with PYTHONHASHSEED=0, one BLAS/OpenMP thread and the cyclic garbage collector frozen after bring-up, as the image
solver does; the counts still move by about 2 % between runs of one build (Unicorn's translation cache and hash
tables), so compare cases within one run and read differences under that as none. With `--top N` the N functions
with the most instructions follow each count (callgrind_annotate).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = ("default", "default-untimed", "full-speed")

# The measured process: bring-up uninstrumented, then `seconds` of board time between the files "go" and "done".
_CHILD = """
import gc, os, sys, time
from host_emulator.construct import build_solver
from host_emulator.scene import load_scene
case, seconds, d = sys.argv[1], float(sys.argv[2]), sys.argv[3]
opts = ["model=image", f"t_end_s={seconds + 1}", "model_options.image.threads=1"]
if case == "default-untimed":
    opts.append("model_options.image.fast_forward_timed=false")
if case == "full-speed":
    from host_emulator.benchmarks.image import full_speed_world
    world, lap = full_speed_world(seconds, 1)
else:
    solver = build_solver(load_scene("default", opts))
    solver.advance()
gc.freeze()
open(os.path.join(d, "ready"), "w").close()
while not os.path.exists(os.path.join(d, "go")):
    time.sleep(0.05)
if case == "full-speed":
    lap.pump(seconds)
else:
    t_end = solver.t + seconds
    while solver.t < t_end - 1e-9:
        solver.advance()
open(os.path.join(d, "done"), "w").close()
while not os.path.exists(os.path.join(d, "stop")):
    time.sleep(0.05)
"""


def _wait(path: Path, proc: subprocess.Popen, what: str) -> None:
    while not path.exists():
        if proc.poll() is not None:
            raise RuntimeError(f"the measured process ended before {what} (exit {proc.returncode})")
        time.sleep(0.2)


def measure(case: str, seconds: float, top: int, keep: Path | None = None) -> tuple[int, list[str]]:
    """(instructions over `seconds` of board time, the top functions' lines); callgrind's output copied to `keep`."""
    with tempfile.TemporaryDirectory(prefix="mc-image-cg-") as tmp:
        d = Path(tmp)
        env = dict(os.environ, PYTHONHASHSEED="0", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        cmd = [
            "valgrind", "--tool=callgrind", "--instr-atstart=no", "--smc-check=all-non-file",
            f"--callgrind-out-file={d / 'out'}", sys.executable, "-c", _CHILD, case, str(seconds), str(d),
        ]  # fmt: skip
        log = open(d / "log", "w")
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
        try:
            _wait(d / "ready", proc, "bring-up ended")
            subprocess.run(["callgrind_control", "-i", "on", str(proc.pid)], check=True, capture_output=True)
            (d / "go").touch()
            _wait(d / "done", proc, "the measured board time ended")
            subprocess.run(["callgrind_control", "-i", "off", str(proc.pid)], check=True, capture_output=True)
            (d / "stop").touch()
            if proc.wait() != 0:
                raise RuntimeError(f"the measured process failed: see {d / 'log'}")
        finally:
            if proc.poll() is None:
                proc.kill()
            log.close()
        if keep is not None:
            shutil.copyfile(d / "out", keep)
        text = (d / "out").read_text(errors="replace")
        m = re.search(r"^totals: (\d+)", text, re.M) or re.search(r"^summary: (\d+)", text, re.M)
        if not m:
            raise RuntimeError("callgrind wrote no total")
        lines: list[str] = []
        if top and shutil.which("callgrind_annotate"):
            ann = subprocess.run(["callgrind_annotate", str(d / "out")], capture_output=True, text=True).stdout
            for ln in ann.splitlines():
                if re.match(r"^\s*[\d,]+ \(\s*[\d.]+%\)\s+\S", ln) and "PROGRAM TOTALS" not in ln:
                    lines.append(re.sub(r" \[[^]]*\]$", "", ln.strip()))
                    if len(lines) == top:
                        break
        return int(m.group(1)), lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.image_instructions",
        description=__doc__.split("\n\n")[0],
    )
    ap.add_argument("--case", nargs="+", choices=CASES, default=list(CASES[:2]), help="cases (default: the first two)")
    ap.add_argument("--seconds", type=float, default=0.1, help="board seconds measured (default 0.1)")
    ap.add_argument("--top", type=int, default=0, help="also the N functions with the most instructions")
    ap.add_argument(
        "--keep", type=Path, default=None, metavar="PREFIX",
        help="also keep callgrind's output of each case as PREFIX.CASE (for callgrind_annotate --inclusive=yes)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    if not 0.01 <= args.seconds <= 2 or not 0 <= args.top <= 50:
        print("benchmark: --seconds 0.01..2, --top 0..50", file=sys.stderr)
        return 2
    keeps = {case: None if args.keep is None else Path(f"{args.keep}.{case}") for case in args.case}
    for path in keeps.values():
        if path is not None and path.exists():
            print(f"benchmark: {path} exists; not overwritten", file=sys.stderr)
            return 2
    for tool in ("valgrind", "callgrind_control"):
        if not shutil.which(tool):
            print(f"benchmark: {tool} is not on the PATH (Debian: valgrind)", file=sys.stderr)
            return 3
    counts = {}
    for case in args.case:
        n, lines = measure(case, args.seconds, args.top, keeps[case])
        counts[case] = n
        rate = n / args.seconds / 1e9
        print(f"{case}: {rate:.3f} G x86 instructions per board second ({n:,} over {args.seconds:g} s)")
        for ln in lines:
            print(f"    {ln}")
    if CASES[0] in counts and CASES[1] in counts:
        a, b = counts[CASES[0]], counts[CASES[1]]
        print(f"default-untimed / default: {b / a:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
