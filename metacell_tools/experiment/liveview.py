"""The live plot in its own process: the runner hands it rows and never waits for a drawing (plot frames drop, data
never does).

`LiveView` stands in for a host_emulator.workbench.trackers.PlotTracker in the runner's process (RigLive feeds it
as it would feed the tracker): `setup`, `sample_many` and `update` only queue what is to be drawn, and a feeder
thread hands the queue to a renderer process (`python -m metacell_tools.experiment.liveview`, started with the
same matplotlib backend) whenever that process has finished its previous drawing. A renderer slower than the
rows simply draws less often, each time with every row since the last; the runner's receive loop, its commands and
its record of them do not wait for it. Before, the redraw ran in the receive loop: the primary's frames piled up
in the port while the figure was saved, a push left late and was recorded with the stale clock.

The renderer runs at a lower priority (nice 10) where the system has one. MC_LIVE_DRAW_DELAY_S=S makes it sleep
S seconds after each drawing: a deliberately slow renderer, for the tests.
"""

from __future__ import annotations

import argparse
import os
import pickle
import struct
import subprocess
import sys
import threading
import time

import numpy as np

HEADER = struct.Struct("<I")  # length of the pickled message that follows
DRAW_DELAY_ENV = "MC_LIVE_DRAW_DELAY_S"


class LiveViewError(RuntimeError):
    """The renderer process did not start or stopped."""


class LiveView:
    """A PlotTracker's feeding end (interval_s, window_s, title, png, interactive, setup, sample_many, update);
    the drawing happens in a renderer process."""

    def __init__(self, interval_ms: float, window_s: float, start_timeout_s: float = 120.0):
        if not (interval_ms > 0 and window_s > 0):
            raise ValueError(f"LiveView: interval_ms ({interval_ms}) and window_s ({window_s}) must be > 0")
        self.interval_s = interval_ms * 1e-3
        self.window_s = float(window_s)
        self.png: str | None = None  # set_png: the file the renderer rewrites at every drawing
        self.title = ""
        self.interactive: bool | None = None  # the renderer says, once its figure exists
        self.draws = 0  # drawings the renderer reported
        self.rows = 0  # rows in the renderer's window after its last message, and the newest one's time
        self.last_t = float("nan")
        self.batches = 0  # messages handed to the renderer
        self.error: str | None = None
        self.start_timeout_s = start_timeout_s
        self._pending: list[tuple] = []
        self._cv = threading.Condition()
        self._ready = False  # the renderer waits for a message
        self._closing = False
        self._hello = threading.Event()
        cmd = [sys.executable, "-m", "metacell_tools.experiment.liveview", f"{interval_ms!r}", f"{window_s!r}"]
        env = dict(os.environ)
        mpl = sys.modules.get("matplotlib")
        chosen = getattr(getattr(mpl, "rcParams", None), "_get_backend_or_none", lambda: None)()
        if chosen:  # a backend this process chose (matplotlib.use): the renderer draws there too
            env["MPLBACKEND"] = chosen
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        self._reader = threading.Thread(target=self._read, name="live-view reader", daemon=True)
        self._writer = threading.Thread(target=self._write, name="live-view feeder", daemon=True)
        self._reader.start()
        self._writer.start()

    # ---- the tracker's interface (what RigLive calls) -------------------------------------------------------------
    def setup(self, n_cells: int, t_end_s: float | None = None, shape: tuple[int, int] | None = None) -> None:
        self._put(("setup", int(n_cells), t_end_s, self.title, None if shape is None else tuple(shape)))

    def sample_many(self, t, alpha, beta) -> None:
        if len(t) == 0:
            return
        self._put(("samples", np.asarray(t, float), np.asarray(alpha, float), np.asarray(beta, float)))

    def update(self) -> None:
        self._put(("update",))

    def set_png(self, png: str) -> None:
        self.png = png
        self._put(("png", png))

    def wait_started(self) -> bool:
        """Wait (bounded) until the renderer has drawn its empty figure; True if it has (interactive is then set)."""
        if not self._hello.wait(self.start_timeout_s) and self.error is None:
            self.error = f"the renderer did not start within {self.start_timeout_s:g} s"
        return self.error is None

    # ---- queue -------------------------------------------------------------------------------------------------
    def _put(self, op: tuple) -> None:
        with self._cv:
            if self.error is not None:
                raise LiveViewError(self.error)  # the runner says it once and goes on without the plot
            if self._closing:
                return
            last = self._pending[-1] if self._pending else None
            if op[0] == "samples" and last is not None and last[0] == "samples":
                t = np.concatenate([last[1], op[1]])
                a, b = np.concatenate([last[2], op[2]]), np.concatenate([last[3], op[3]])
                keep = t >= t[-1] - self.window_s - 1e-12  # older rows are out of the window: never drawn
                self._pending[-1] = ("samples", t[keep], a[keep], b[keep])
            elif op[0] == "update" and last is not None and last[0] == "update":
                pass
            else:
                if op[0] == "setup":  # a new repeat: rows and redraws of the old one are not drawn any more
                    self._pending = [p for p in self._pending if p[0] == "png"]
                self._pending.append(op)
            self._cv.notify_all()

    def _write(self) -> None:
        pipe = self.proc.stdin
        assert pipe is not None
        while True:
            ops = None
            with self._cv:
                while self.error is None:
                    if self._ready and self._pending:
                        ops, self._pending, self._ready = self._pending, [], False
                        break
                    if self._closing and (not self._pending or self.proc.poll() is not None):
                        break
                    self._cv.wait(0.5 if self._closing else None)
            if ops is None:
                break
            data = pickle.dumps(ops, protocol=pickle.HIGHEST_PROTOCOL)
            try:
                pipe.write(HEADER.pack(len(data)) + data)
                pipe.flush()
            except (OSError, ValueError) as e:
                self._fail(f"the renderer stopped reading: {e}")
                break
            self.batches += 1
        try:
            pipe.close()
        except OSError:
            pass

    def _read(self) -> None:
        out = self.proc.stdout
        assert out is not None
        for raw in out:
            line = raw.decode(errors="replace").strip()
            word, _, rest = line.partition(" ")
            if word in ("hello", "ready"):
                fields = dict(kv.split("=", 1) for kv in rest.split() if "=" in kv)
                with self._cv:
                    self.draws = int(fields.get("draws", self.draws))
                    self.rows = int(fields.get("rows", self.rows))
                    self.last_t = float(fields.get("last_t", self.last_t))
                    if word == "hello":
                        self.interactive = fields.get("interactive") == "1"
                        self._hello.set()
                    self._ready = True
                    self._cv.notify_all()
            elif word == "error":
                self._fail(rest)
        self._fail("the renderer exited")

    def _fail(self, why: str) -> None:
        with self._cv:
            if self.error is None and not (self._closing and why == "the renderer exited"):
                self.error = why
            self._hello.set()
            self._cv.notify_all()

    # ---- end -----------------------------------------------------------------------------------------------------
    def close(self, timeout_s: float = 60.0) -> None:
        """Hand over what is queued (bounded wait), then end the input: a renderer drawing to a file exits, one with
        a window keeps it until it is closed (`wait`)."""
        with self._cv:
            self._closing = True
            self._cv.notify_all()
        self._writer.join(timeout_s)
        if self._writer.is_alive():  # the renderer is stuck: stop it rather than hang the command
            self.terminate()

    def wait(self, timeout_s: float | None = None) -> int | None:
        """Wait for the renderer to exit (its window closed); None on timeout."""
        try:
            return self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def terminate(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)


# ---- the renderer process ------------------------------------------------------------------------------------------
def _read_message(stream) -> list | None:
    head = stream.read(HEADER.size)
    if len(head) < HEADER.size:
        return None
    (size,) = HEADER.unpack(head)
    data = stream.read(size)
    if len(data) < size:
        return None
    return pickle.loads(data)


def render(interval_ms: float, window_s: float, stdin=None, stdout=None) -> int:
    """Draw the messages arriving on stdin with a PlotTracker; say hello (after the first set-up) and ready (after
    each message) on stdout. At the end of the input a window stays open until it is closed."""
    import signal

    from host_emulator.workbench.trackers import PlotTracker

    stdin = stdin or sys.stdin.buffer
    stdout = stdout or sys.stdout
    if hasattr(signal, "SIGINT"):
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the runner's: it switches the drive off, then stops us
    try:
        os.nice(10)
    except (AttributeError, OSError):
        pass
    delay = float(os.environ.get(DRAW_DELAY_ENV) or 0.0)
    tracker = PlotTracker(interval_ms, window_s)
    if delay > 0:
        draw = tracker.update

        def slow_update():
            draw()
            time.sleep(delay)

        tracker.update = slow_update  # type: ignore[method-assign]
    said_hello = False
    print("ready draws=0", file=stdout, flush=True)
    while True:
        msg = _read_message(stdin)
        if msg is None:
            break
        for op in msg:
            kind = op[0]
            if kind == "setup":
                tracker.title = op[3]
                tracker.setup(op[1], op[2], op[4] if len(op) > 4 else None)
            elif kind == "samples":
                tracker.sample_many(op[1], op[2], op[3])
            elif kind == "update":
                tracker.update()
            elif kind == "png":
                tracker.png = op[1]
        state = f"draws={tracker.draws}"
        if tracker.image is not None:  # set up: what the window holds (the runner's tests read it)
            t = tracker.window()[0]
            state += f" rows={len(t)} last_t={float(t[-1]) if len(t) else float('nan')!r}"
        if not said_hello and tracker.image is not None:
            said_hello = True
            print(f"hello interactive={int(tracker.interactive)} {state}", file=stdout, flush=True)
        else:
            print(f"ready {state}", file=stdout, flush=True)
    if tracker.image is not None and tracker.interactive:
        from matplotlib import pyplot as plt

        plt.show()
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.experiment.liveview", description=(__doc__ or "").split("\n")[0]
    )
    ap.add_argument("interval_ms", type=float)
    ap.add_argument("window_s", type=float)
    args = ap.parse_args(argv)
    try:
        return render(args.interval_ms, args.window_s)
    except Exception as e:  # noqa: BLE001 - said to the runner in one line, which reports it once
        print(f"error {type(e).__name__}: {e}", flush=True)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
