"""Animation of the lattice forming its pattern: `python -m host_emulator animate SCENE --out lattice.gif`.

Each cell is drawn from above as two discs, the tall (alpha) cylinder and the short (beta) one, with a
pointer at its angle; the strip below shows the alpha profile. A 2-D sheet is drawn as its field of alpha (an
image, or hexagons on a hexagonal sheet; sheet_plots.py) changing in time. GIF through Pillow (a matplotlib
dependency) or MP4 through the ffmpeg that imageio-ffmpeg ships (``--out lattice.mp4``; the project's
``video`` extra, in ``dev`` too). Without a working ffmpeg an MP4 request writes a GIF of the same name
instead and says why.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..models import ConfigError, NumericalInstability
from ..outpaths import check_out_file
from ..progress import bar
from .api import run
from .plots import _title, cell_ticks

MP4_HINT = "pip install imageio-ffmpeg, or the project's extra: pip install 'metamaterial-rig[video]'"


def ffmpeg_exe() -> tuple[str | None, str]:
    """(path of a working ffmpeg from imageio-ffmpeg, "") or (None, why not)."""
    try:
        import imageio_ffmpeg
    except ImportError:
        return None, f"MP4 needs imageio-ffmpeg, which is not installed ({MP4_HINT})"
    try:
        return imageio_ffmpeg.get_ffmpeg_exe(), ""
    except Exception as e:  # noqa: BLE001 - RuntimeError when no binary fits this platform
        return None, f"imageio-ffmpeg found no ffmpeg binary ({e})"


def animate(run, path, *, fps=20, t_max=None, every=None, scene=None, fallback=True, report=None, quiet=True):
    """Write an animation of run (a RunResult) to path (.gif or .mp4); returns the path written.

    An .mp4 needs imageio-ffmpeg's ffmpeg; without one (or if it fails) and with `fallback`, the GIF of the
    same name is written instead, `report(message)` says why (default: a warning), and its path is returned.
    quiet=False: a progress bar over the frames drawn (on a terminal only)."""
    from matplotlib.animation import FuncAnimation
    from matplotlib.figure import Figure

    path = str(path)
    if not path.endswith((".gif", ".mp4")):
        raise ValueError(f"{path}: the animation is written as .gif or .mp4")
    exe, why = ffmpeg_exe() if path.endswith(".mp4") else (None, "")
    if path.endswith(".mp4") and exe is None and not fallback:
        raise RuntimeError(f"{why}; or write a .gif")

    t = np.asarray(getattr(run, "time", None) if getattr(run, "time", None) is not None else run.t)
    a, b = np.asarray(run.alpha), np.asarray(run.beta)
    scene = scene if scene is not None else getattr(run, "scene", None)
    k_end = len(t) if t_max is None else int(np.searchsorted(t, t_max, side="right"))
    frames = list(range(0, max(1, k_end), max(1, every or int(np.ceil(k_end / (fps * 10))))))
    topo = getattr(scene, "topology", None)
    if topo is not None and topo.is_sheet:
        sheet_fig, sheet_draw = _sheet_frames(t, a, topo, scene, k_end)
        anim = FuncAnimation(sheet_fig, sheet_draw, frames=frames, blit=False)
        return _write(anim, path, frames, fps, exe, why, fallback, report, quiet)
    n = a.shape[1]
    x = np.arange(1, n + 1)
    fig = Figure(figsize=(9, 3.6), constrained_layout=True)
    top, bot = fig.subplots(2, 1, gridspec_kw={"height_ratios": [1.2, 1]})
    top.set_xlim(0.3, n + 0.7)
    top.set_ylim(-0.9, 0.9)
    top.set_aspect("equal")
    top.axis("off")
    for j in x:
        top.add_patch(__import__("matplotlib.patches", fromlist=["Circle"]).Circle((j, 0.35), 0.33, fc="0.9", ec="0.5"))
        top.add_patch(
            __import__("matplotlib.patches", fromlist=["Circle"]).Circle((j, -0.45), 0.28, fc="0.95", ec="0.6")
        )
    (pa,) = top.plot([], [], "-", color="C0", lw=2)
    (pb,) = top.plot([], [], "-", color="C1", lw=2)
    lim = float(np.abs(a[:k_end]).max()) or 1.0
    bot.set_xlim(0.5, n + 0.5)
    bot.set_ylim(-1.1 * lim, 1.1 * lim)
    bot.axhline(0, color="0.7", lw=0.8)
    bot.set_xlabel("cell j")
    cell_ticks(bot.xaxis, n)
    bot.set_ylabel("alpha (rad)")
    (prof,) = bot.plot([], [], "o-", color="C0")
    txt = top.set_title("", fontsize=9)

    def seg(y0, r, ang):
        xs = np.column_stack([x, x + r * np.cos(np.pi / 2 + ang), np.full(n, np.nan)]).ravel()
        ys = np.column_stack([np.full(n, y0), y0 + r * np.sin(np.pi / 2 + ang), np.full(n, np.nan)]).ravel()
        return xs, ys

    def draw(k):
        pa.set_data(*seg(0.35, 0.33, a[k]))
        pb.set_data(*seg(-0.45, 0.28, b[k]))
        prof.set_data(x, a[k])
        txt.set_text(_title(scene, f"t = {t[k]:.2f} s") if scene is not None else f"t = {t[k]:.2f} s")
        return pa, pb, prof, txt

    anim = FuncAnimation(fig, draw, frames=frames, blit=False)
    return _write(anim, path, frames, fps, exe, why, fallback, report, quiet)


def _sheet_frames(t, a, topo, scene, k_end):
    """(Figure, draw(k)) of a sheet's animation: its alpha field at sample k, one colour scale for the whole run."""
    from matplotlib.figure import Figure

    from .sheet_plots import draw_field, set_field

    w = 5.0 * max(0.6, min(1.6, topo.cols / topo.rows)) + 1.2
    fig = Figure(figsize=(w, 4.6), constrained_layout=True)
    ax = fig.add_subplot(111)
    lim = float(np.abs(a[:k_end]).max()) or 1.0
    m = draw_field(ax, a[0], topo, lim)
    fig.colorbar(m, ax=ax, label="alpha (rad)", shrink=0.85)
    txt = ax.set_title("", fontsize=9)

    def draw(k):
        set_field(m, a[k], topo)
        txt.set_text(_title(scene, f"t = {t[k]:.2f} s") if scene is not None else f"t = {t[k]:.2f} s")
        return m, txt

    return fig, draw


def _write(anim, path, frames, fps, exe, why, fallback, report, quiet):
    """Save the animation with a progress bar over its frames (_save_animation); returns the path written."""
    pbar = bar(len(frames), desc=f"animate {path.rsplit('/', 1)[-1]}", unit="frame", quiet=quiet)

    def advance(i: int, total: int) -> None:
        pbar.n = i + 1
        pbar.refresh()

    try:
        return _save_animation(anim, path, fps, exe, why, fallback, report, advance)
    finally:
        pbar.close()


def _save_animation(anim, path, fps, exe, why, fallback, report, advance):
    if path.endswith(".mp4"):
        if exe is not None:
            from matplotlib import rc_context
            from matplotlib.animation import FFMpegWriter

            try:
                with rc_context({"animation.ffmpeg_path": exe}):
                    anim.save(
                        path,
                        writer=FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"]),
                        progress_callback=advance,
                    )
                return path
            except Exception as e:  # noqa: BLE001 - ffmpeg exits non-zero, cannot start, ...
                why = f"ffmpeg failed ({type(e).__name__}: {e})"
        if not fallback:
            raise RuntimeError(f"{why}; or write a .gif")
        gif = path[: -len(".mp4")] + ".gif"
        msg = f"{why}: wrote the GIF {gif} instead of {path}"
        if report is None:
            import warnings

            warnings.warn(msg, RuntimeWarning, stacklevel=2)
        else:
            report(msg)
        path = gif
    from matplotlib.animation import PillowWriter

    anim.save(path, writer=PillowWriter(fps=fps), progress_callback=advance)
    return path


def animate_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator animate",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  python -m host_emulator animate default --out lattice.gif\n"
        "  python -m host_emulator animate exp1_ccw_ccw --t-max 1.5 --fps 15 "
        "--out exp1.gif\n"
        "  python -m host_emulator animate default --out lattice.mp4    # needs imageio-ffmpeg (extra 'video')",
    )
    ap.add_argument("scene", help="shipped scene name or .toml path")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override, as for run")
    ap.add_argument(
        "--out",
        required=True,
        help="output file, .gif (Pillow) or .mp4 (imageio-ffmpeg; without it the .gif of the same name, said why)",
    )
    ap.add_argument("--fps", type=int, default=20, help="frames per second of the animation (default 20)")
    ap.add_argument(
        "--t-max",
        type=float,
        default=2.0,
        help="animate up to this simulated time, s (default 2: the pattern forms in the first 0.5 s)",
    )
    ap.add_argument("--quiet", action="store_true", help="no progress bars (they show on a terminal only anyway)")
    args = ap.parse_args(argv)
    if not (1 <= args.fps <= 60) or not args.t_max > 0:
        print("error: --fps must be 1..60 and --t-max > 0", file=sys.stderr)
        return 2
    problem = check_out_file(args.out, "--out", (".gif", ".mp4"))
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    try:
        r = run(args.scene, list(args.set), progress=not args.quiet)
        written = animate(
            r,
            args.out,
            fps=args.fps,
            t_max=args.t_max,
            report=lambda m: print(f"note: {m}", file=sys.stderr),
            quiet=args.quiet,
        )
    except (ConfigError, ValueError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except NumericalInstability as e:
        print(f"error: run stopped: {e}", file=sys.stderr)
        return 3
    print(f"wrote {written}")
    return 0
