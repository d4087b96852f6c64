"""Trackers called by the controller at every output sample (or per chunk of samples): live printing and a live
plot (rolling space-time map and the current angle profile). The base class, recording and the progress bar live
below the controller (host_emulator/tracking.py) and are importable from here too."""

from __future__ import annotations

import sys
import time
import warnings
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..tracking import ProgressTracker, RecordTracker, Tracker
from .plots import cell_ticks

__all__ = ["Tracker", "RecordTracker", "ProgressTracker", "LiveTracker", "PlotTracker"]

if TYPE_CHECKING:
    from matplotlib.image import AxesImage

    from ..models import Solver


class LiveTracker(Tracker):
    """Prints max |alpha|, |beta| every `every_s` simulated seconds (for watching a long run)."""

    def __init__(self, every_s: float = 1.0, file: TextIO | None = None) -> None:
        self.every_s = every_s
        self.file = file or sys.stdout

    def start(self, solver: Solver, t_end_s: float, n_samples: int) -> None:
        self.next = 0.0
        self.t0 = time.perf_counter()

    def sample(self, t: float, alpha: np.ndarray, beta: np.ndarray) -> None:
        if t + 1e-12 >= self.next:
            print(
                f"t={t:7.3f} s  max|alpha|={np.abs(alpha).max():.4f}  max|beta|={np.abs(beta).max():.4f} rad",
                file=self.file,
            )
            self.next += self.every_s


class PlotTracker(Tracker):
    """Live plot: a rolling space-time map of alpha over the last `window_s` and the current alpha/beta profile.

    Redrawn every `interval_ms` of simulated (or, on the rig, primary-clock) time; a chunk of samples that spans
    several intervals is drawn once, with its newest sample. Draws into `fig` (a matplotlib Figure) when given;
    otherwise opens a pyplot window. The package never selects a backend: on a non-interactive one (Agg, a
    headless machine) no window can appear, so give `png=` to have the figure written there at every redraw.

    Used by the emulator (`python -m host_emulator run SCENE --live`, through the controller) and by the rig
    (`python -m metacell_tools.experiment run ... --live`, fed with `setup()` and `sample_many()` from the logged
    frames).
    After a draw, `image.get_array()` is the alpha window drawn (rows: time, oldest first; columns: cells) and
    `window()` returns the (t, alpha, beta) it came from. On a sheet (setup's `shape` = (rows, cols)) the right
    panel is the current alpha field instead of the profile: `field.get_array()` is the newest row as
    (rows, cols), cell (row, col) = alpha of cell (row - 1) * cols + col."""

    def __init__(
        self,
        interval_ms: float = 100.0,
        window_s: float = 2.0,
        *,
        fig=None,
        png: str | None = None,
        title: str = "",
        max_rows: int = 4000,
    ):
        if not (interval_ms > 0 and window_s > 0 and max_rows >= 2):
            raise ValueError(
                f"PlotTracker: interval_ms ({interval_ms}) and window_s ({window_s}) must be > 0, max_rows >= 2"
            )
        self.interval_s = interval_ms * 1e-3
        self.window_s = float(window_s)
        self.fig = fig
        self.png = png
        self.title = title
        self.max_rows = int(max_rows)
        self.draws = 0
        self.image: AxesImage | None = None  # the space-time map, made by setup()

    # ---- set-up ----------------------------------------------------------------------------------------------
    def start(self, solver: Solver, t_end_s: float, n_samples: int) -> None:
        params = getattr(solver.model, "params", None)
        topology = getattr(params, "topology", None)
        self.setup(solver.model.n, t_end_s, topology.shape if topology is not None and topology.is_sheet else None)

    def setup(self, n_cells: int, t_end_s: float | None = None, shape: tuple[int, int] | None = None) -> None:
        """Empty buffers for n_cells cells and a fresh figure layout (also the entry point for non-solver feeds);
        shape (rows, cols) draws a sheet's current field (rows * cols must be n_cells)."""
        self.n = int(n_cells)
        if shape is not None:
            rows, cols = (int(v) for v in shape)
            if rows < 1 or cols < 1 or rows * cols != self.n:
                raise ValueError(f"PlotTracker: a {rows} x {cols} sheet does not hold {self.n} cells")
            shape = (rows, cols)
        self.shape = shape
        self.field: AxesImage | None = None
        self.t_end_s = t_end_s
        self._t = np.empty(0)
        self._a = np.empty((0, self.n))
        self._b = np.empty((0, self.n))
        self._pending: list[tuple] = []
        self._next = 0.0
        self._layout()

    def _layout(self):
        if self.fig is None:
            from matplotlib import pyplot as plt

            self.fig = plt.figure(figsize=(9, 4.2), layout="constrained")
            self._pyplot = True
        else:
            self._pyplot = False
            self.fig.clear()
        self.ax_map, self.ax_prof = self.fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.3, 1]})
        self.image = self.ax_map.imshow(
            np.zeros((2, self.n)),
            origin="lower",
            aspect="auto",
            cmap="RdBu_r",
            interpolation="nearest",
            extent=(0.5, self.n + 0.5, 0.0, self.window_s),
        )
        self.fig.colorbar(self.image, ax=self.ax_map, label="alpha (rad)")
        self.ax_map.set_xlabel("cell j")
        cell_ticks(self.ax_map.xaxis, self.n)
        self.ax_map.set_ylabel("t (s)")
        if self.shape is not None:
            rows, cols = self.shape
            self.field = self.ax_prof.imshow(
                np.zeros(self.shape),
                cmap="RdBu_r",
                interpolation="nearest",
                extent=(0.5, cols + 0.5, rows + 0.5, 0.5),
            )
            self.ax_prof.set_xlabel("col")
            self.ax_prof.set_ylabel("row")
        else:
            x = np.arange(1, self.n + 1)
            (self.line_a,) = self.ax_prof.plot(x, np.zeros(self.n), "o-", color="C0", label="alpha")
            (self.line_b,) = self.ax_prof.plot(x, np.zeros(self.n), "s--", color="C1", ms=3, label="beta")
            self.ax_prof.axhline(0, color="0.7", lw=0.8)
            self.ax_prof.set_xlim(0.5, self.n + 0.5)
            self.ax_prof.set_xlabel("cell j")
            cell_ticks(self.ax_prof.xaxis, self.n)
            self.ax_prof.set_ylabel("angle (rad)")
            self.ax_prof.legend(loc="upper right", fontsize=8)
        self.interactive = getattr(type(self.fig.canvas), "required_interactive_framework", None) is not None
        if self._pyplot and self.interactive:
            from matplotlib import pyplot as plt

            plt.show(block=False)

    # ---- samples ---------------------------------------------------------------------------------------------
    def sample(self, t, alpha, beta):
        self._pending.append((np.array([t], float), np.asarray(alpha, float)[None], np.asarray(beta, float)[None]))
        if t + 1e-12 >= self._next:
            self.update()

    def sample_many(self, t, alpha, beta):
        if len(t) == 0:
            return
        self._pending.append((np.asarray(t, float), np.asarray(alpha, float), np.asarray(beta, float)))
        if t[-1] + 1e-12 >= self._next:
            self.update()

    def _flush(self):
        if not self._pending:
            return
        t = np.concatenate([self._t] + [p[0] for p in self._pending])
        a = np.concatenate([self._a] + [p[1] for p in self._pending])
        b = np.concatenate([self._b] + [p[2] for p in self._pending])
        self._pending = []
        keep = (t >= t[-1] - self.window_s - 1e-12) & (np.arange(len(t)) >= len(t) - self.max_rows)
        self._t, self._a, self._b = t[keep], a[keep], b[keep]

    def window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, alpha, beta) of the rolling window (after folding in the samples not yet drawn)."""
        self._flush()
        return self._t, self._a, self._b

    # ---- drawing ---------------------------------------------------------------------------------------------
    def update(self) -> None:
        """Redraw now with every sample received so far; the next redraw is one interval after the newest sample."""
        t, a, b = self.window()
        if len(t) == 0:
            return
        image = self.image
        if image is None:
            raise RuntimeError("PlotTracker: setup() (or start()) before update()")
        self._next = float(t[-1]) + self.interval_s
        image.set_data(a)
        lo, hi = float(t[0]), float(t[-1])
        image.set_extent((0.5, self.n + 0.5, lo, hi if hi > lo else lo + 1e-6))
        lim = float(np.abs(a).max()) or 1e-3
        image.set_clim(-lim, lim)
        if self.field is not None:
            self.field.set_data(a[-1].reshape(self.shape))
            self.field.set_clim(-lim, lim)
            self.ax_prof.set_title("current field (alpha)", fontsize=9)
        else:
            self.line_a.set_ydata(a[-1])
            self.line_b.set_ydata(b[-1])
            plim = max(float(np.abs(a[-1]).max()), float(np.abs(b[-1]).max())) or 1e-3
            self.ax_prof.set_ylim(-1.15 * plim, 1.15 * plim)
            self.ax_prof.set_title("current profile", fontsize=9)
        self.ax_map.set_title(f"{self.title}  t = {hi:.2f} s".strip(), fontsize=9)
        self.draws += 1
        if self.interactive:
            self.fig.canvas.draw_idle()
            self.fig.canvas.flush_events()
        if self.png:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                self.fig.savefig(self.png, dpi=80)

    def finish(self):
        self.update()
