"""Python API: he.run -> RunResult, to_xarray, plots with ax=, no backend switch, provenance; the notebook runs."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[3]


def test_run_result_and_xarray():
    import host_emulator as he

    r = he.run("default", overrides={"t_end_s": 0.5, "params.sigma": 0.05})
    assert r.time.shape == (51,) and r.alpha.shape == (51, 16) and r.beta.shape == (51, 16)
    assert r.scene.params.sigma == 0.05
    ds = r.to_xarray()
    assert ds.alpha.dims == ("time", "cell") and ds.alpha.attrs["units"] == "rad"
    assert ds.time.attrs["units"] == "s" and list(ds.cell.values) == list(range(1, 17))
    assert ds.attrs["params.sigma"] == 0.05 and ds.attrs["perturbation.1.cell"] == 8
    assert ds.attrs["provenance.git_describe"] and ds.attrs["provenance.firmware_build"] != "unknown"
    np.testing.assert_array_equal(ds.alpha.values, r.alpha)
    # the same numbers as the CLI's run path
    from host_emulator.controller import run_scene
    from host_emulator.scene import load_scene

    ref = run_scene(load_scene("default", ["t_end_s=0.5", "params.sigma=0.05"]), progress=False)
    np.testing.assert_array_equal(ref.alpha, r.alpha)


def test_run_bad_key_is_a_clear_error():
    import host_emulator as he
    from host_emulator.models import ConfigError

    with pytest.raises(ConfigError, match="params.sigmaa"):
        he.run("default", overrides={"params.sigmaa": 0.05})


def test_plots_take_ax_and_leave_the_backend_alone(tmp_path):
    import matplotlib

    before = matplotlib.get_backend()
    from matplotlib.figure import Figure

    import host_emulator as he

    r = he.run("default", overrides={"t_end_s": 0.6})
    fig = Figure()
    axes = fig.subplots(2, 2)
    assert he.plot_spacetime(r, ax=axes) is fig
    ax = Figure().add_subplot(111)
    assert he.plot_final(r, ax=ax) is ax.figure
    assert he.plot_dispersion(r.scene.params, ax=ax, inertia=True) is ax.figure
    f2 = he.plot_spacetime(r)
    f2.savefig(tmp_path / "s.png")
    assert (tmp_path / "s.png").stat().st_size > 1000
    assert "sigma = 0.072" in f2.axes[0].get_title()
    assert matplotlib.get_backend() == before


def test_package_never_selects_a_backend():
    hits = [
        str(p)
        for d in ("host_emulator", "metacell_tools")
        for p in (ROOT / d).rglob("*.py")
        if re.search(r"matplotlib\.use\(|pyplot\.switch_backend|plt\.switch_backend", p.read_text())
    ]
    assert hits == []


def test_summary_json_names_the_code_version(tmp_path):
    from host_emulator.cli import main

    assert main(["run", "default", "--set", "t_end_s=0.3", "--out", str(tmp_path), "--quiet", "--no-plots"]) == 0
    prov = json.loads((tmp_path / "summary.json").read_text())["provenance"]
    for k in (
        "package_version",
        "git_describe",
        "firmware_build",
        "numpy",
        "scipy",
        "python_can",
        "created_utc",
        "command",
        "python",
    ):
        assert prov[k], k
    assert re.fullmatch(r"[0-9a-f]{16}", prov["firmware_build"])


def test_example_notebook_executes():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(ROOT / "docs" / "workbench.ipynb", as_version=4)
    nbclient.NotebookClient(
        nb, timeout=240, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}
    ).execute()
    images = [
        o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if "image/png" in o.get("data", {})
    ]
    assert len(images) >= 3  # figures show inline: the backend was not switched to Agg


def test_animate_and_dispersion_plot_commands(tmp_path, capsys):
    from host_emulator.cli import main

    gif = tmp_path / "a.gif"
    assert main(["animate", "default", "--set", "t_end_s=0.3", "--t-max", "0.2", "--fps", "5", "--out", str(gif)]) == 0
    from PIL import Image

    assert Image.open(gif).n_frames >= 2
    assert main(["animate", "default", "--out", str(tmp_path / "a.avi")]) == 2
    assert not (tmp_path / "a.avi").exists()
    png = tmp_path / "d.png"
    assert main(["dispersion", "--sigma", "9/125", "--inertia", "--cells", "16", "--plot", str(png)]) == 0
    assert png.stat().st_size > 5000


def test_dispersion_plot_names_band_and_fastest_wavelength():
    from matplotlib.figure import Figure

    import host_emulator as he
    from host_emulator.params import Params

    ax = Figure().add_subplot(111)
    he.plot_dispersion(Params(sigma=0.072), ax=ax, inertia=True, measured_period_s=None)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(s.startswith("stationary unstable 5.79-21.6") for s in labels) and any(
        s.startswith("fastest wavelength") for s in labels
    )
    assert "lattice with inertia" in ax.get_title() and "(1/s)" in ax.get_ylabel()
    # 12/125 at the table k: both pieces of the unstable set are drawn, each with its kind
    ax = Figure().add_subplot(111)
    he.plot_dispersion(Params(sigma=12 / 125, band_scale=0.5), ax=ax, inertia=True)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "stationary unstable 4.51-7.54 cells" in labels and "oscillatory unstable 19.3-inf cells" in labels
    ticks = [t.get_text() for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
    assert ticks and all("^" not in s and "times" not in s for s in ticks)  # plain numbers, no 10^x labels


def test_did_you_mean_for_scenes_and_keys():
    from host_emulator.models import ConfigError
    from host_emulator.scene import load_scene

    with pytest.raises(ConfigError, match="did you mean 'default'"):
        load_scene("defualt")
    with pytest.raises(ConfigError, match="did you mean 'sigma'"):
        load_scene("default", ["params.sigmaa=0.05"])
    with pytest.raises(ConfigError, match="did you mean 't_end_s'"):
        load_scene("default", ["t_end=1"])


def _tiny_run(frames=12, cells=4):
    """A RunResult-like object with known angles (no simulation needed to test the writers)."""
    from types import SimpleNamespace

    t = np.linspace(0.0, 0.55, frames)
    a = 0.5 * np.sin(np.outer(t + 0.1, np.arange(1, cells + 1)))
    return SimpleNamespace(t=t, alpha=a, beta=-0.3 * a, scene=None)


def test_animate_writes_mp4_through_imageio_ffmpeg(tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    from host_emulator.workbench.animate import animate

    out = animate(_tiny_run(), tmp_path / "a.mp4", fps=10, every=1, report=pytest.fail)
    assert out == str(tmp_path / "a.mp4")
    head = (tmp_path / "a.mp4").read_bytes()[:12]
    assert head[4:8] == b"ftyp"  # an ISO media file
    n, secs = imageio_ffmpeg.count_frames_and_secs(out)
    assert n == 12 and secs == pytest.approx(1.2, abs=0.11)  # every sample one frame at 10 fps


def test_animate_mp4_without_imageio_ffmpeg_falls_back_to_gif(tmp_path, monkeypatch, capsys):
    """No imageio-ffmpeg: the GIF of the same name, and a message naming the package to install."""
    from PIL import Image

    from host_emulator.cli import main
    from host_emulator.workbench import animate as A

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails as if not installed
    notes = []
    out = A.animate(_tiny_run(), tmp_path / "b.mp4", fps=10, every=1, report=notes.append)
    assert out == str(tmp_path / "b.gif") and not (tmp_path / "b.mp4").exists()
    assert len(notes) == 1 and "imageio-ffmpeg" in notes[0] and "b.gif" in notes[0]
    with Image.open(out) as im:
        assert im.n_frames == 12
    with pytest.raises(RuntimeError, match="imageio-ffmpeg"):
        A.animate(_tiny_run(), tmp_path / "c.mp4", fallback=False)
    # the command line says it on stderr and names the file it wrote
    assert main(["animate", "default", "--set", "t_end_s=0.2", "--t-max", "0.1", "--fps", "5",
                 "--out", str(tmp_path / "d.mp4")]) == 0  # fmt: skip
    io = capsys.readouterr()
    assert "note: MP4 needs imageio-ffmpeg" in io.err and f"wrote {tmp_path / 'd.gif'}" in io.out


def test_no_submodule_shadows_an_api_function():
    """A notebook re-runs its cells: after every module of the package is imported, each API name is still the
    function (he.sweep was the submodule after its first call), and he.sweep is callable twice."""
    code = (
        "import importlib, pkgutil, types, host_emulator as he\n"
        "for m in pkgutil.walk_packages(he.__path__, 'host_emulator.'):\n"
        "    if m.name.endswith('__main__'):\n"
        "        continue\n"
        "    try:\n"
        "        importlib.import_module(m.name)\n"
        "    except ImportError:\n"
        "        pass  # a benchmark peer of the bench extra\n"
        "bad = [n for n in he.__all__ if isinstance(getattr(he, n), types.ModuleType)]\n"
        "assert not bad, bad\n"
        "assert callable(he.sweep) and callable(he.load) and callable(he.run)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
