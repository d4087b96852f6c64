"""`python -m host_emulator paper --out DIR`: the source paper's Fig. 2 and Fig. 3 regenerated, item by item against its
numbers.

Each item is one number the source reports (a regime, a pattern's wavelength, an oscillation's period, rest)
beside ours, with an agreement rule written next to it:

* regimes: equal names (analysis.stability.REGIMES). Ours is the linear theory of the lattice with inertia (the
  model of the exp. 3 scenes); the source's classification, made without inertia, is translated to those names
  (``SIGMAS``): conditionally unstable = stationary_pattern, unconditionally unstable = broadband_pattern, and
  at 14/125, which its overdamped theory calls stable, the steady 0.03 s uniform oscillation its rig and its
  Fig. 2c.ii show = uniform_oscillation. The overdamped theory's regime is given in each item's note;
* patterns: the source reads lambda = 30 / Z for Z domain walls over the 16-cell chain; ours agrees when
  the run selects the same Z (``observables.domain_walls``). With repeats (the hil noise model), the
  majority of repeats must select it, and the fraction is reported;
* oscillation periods: within ``PERIOD_TOL`` (10 %) of the source's 0.03 s, which it gives to one digit;
* rest: ``observables.at_rest`` (every cylinder within three encoder counts).

The repeats of Fig. 3 use the hil model with a realistic noise model (``NOISE``: 5 % spread of the band pairs'
stiffness and of the honey cups' viscosity), each repeat its own seed, as the rig's ten hand-pushed repeats
differ. No encoder jitter: an optical quadrature encoder at rest reads a steady count, and a jittering reading
(0.5 count rms) is itself a push that grows a pattern out of rest at 9/125 (measured: 10 of 10 repeats).
Figures are drawn with matplotlib's object API (no backend is chosen).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from ..analysis.observables import observables
from ..analysis.stability import Theory, dispersion, format_set
from ..construct import scene_cost
from ..controller import run_scene
from ..limits import batch_budget
from ..outpaths import check_out_dir
from ..params import Params
from ..progress import bar
from ..scene import load_scene
from .plots import cell_ticks

PERIOD_TOL = 0.10
SOURCE_PERIOD_S = 0.03
NOISE = {"band_spread": 0.05, "eta_spread": 0.05}
# Fig. 2 panel -> (sigma as the source writes it, value, the source's classification, in our regime names)
SIGMAS = {
    "a": ("9/125", 9 / 125, "conditionally unstable", "stationary_pattern"),
    "b": ("6/125", 6 / 125, "unconditionally unstable", "broadband_pattern"),
    "c": ("14/125", 14 / 125, "stable; a steady 0.03 s oscillation on its rig (2c.ii)", "uniform_oscillation"),
}
THEORY = Theory("lattice", inertia=True, discrete=True)  # the theory of the model the exp. 3 scenes run
# Fig. 2 a.ii-c.ii (one push on alpha_8) and Fig. 3 (rest, symmetric, antisymmetric loading)
FIG2_RUNS: dict[str, tuple[str, list[str], int]] = {
    "a": ("exp3_single_sigma9", [], 4),
    "b": ("exp3_single_sigma6", [], 2),
}
FIG3_RUNS = {"a": ("exp5_rest", 0), "b": ("exp1_ccw_ccw", 2), "c": ("exp2_ccw_cw", 3)}
# each run item's noise-seed check: (scene, overrides, the source's result, with encoder jitter too); the scenes
# of `robustness` run as it runs them (its model: hil wherever the rig's noise is modelled), so the fractions are
# its figures
SEED_CHECKS: dict[str, tuple[str, list[str], object, bool]] = {
    "2a.ii": ("exp3_single_sigma9", ["model=hil"], 4, True),
    "2b.ii": ("exp3_single_sigma6", ["model=hil"], 2, True),
    "2c.ii lattice": ("exp3_single_sigma14", ["model=lattice"], SOURCE_PERIOD_S, False),
    "2c.ii hil": ("exp3_single_sigma14", ["model=hil", "params.bemf_comp=true"], SOURCE_PERIOD_S, True),
    "exp. 4": ("exp4_stable_eta10", ["model=hil"], "rest", True),
    "3a": ("exp5_rest", ["model=hil"], "rest", True),
    "3b": ("exp1_ccw_ccw", ["model=hil"], 2, True),
    "3c": ("exp2_ccw_cw", ["model=hil"], 3, True),
}
DEFAULT_SEEDS = 20


@dataclass
class Item:
    figure: str
    what: str
    source: object
    ours: object
    agree: bool
    note: str = ""
    extra: dict = field(default_factory=dict)
    # the noise-seed check of an item that comes from runs: (scene, overrides, the source's result, jitter too)
    check: tuple[str, list[str], object, bool] | None = None
    seeds: float | None = None  # fraction of the noise seeds selecting the source's result
    seeds_jitter: float | None = None  # the same with encoder jitter (hil runs only)

    def as_dict(self) -> dict:
        return {
            "figure": self.figure,
            "item": self.what,
            "source": self.source,
            "ours": self.ours,
            "agree": bool(self.agree),
            "note": self.note,
            **self.extra,
            "seeds": self.seeds,
            "seeds_jitter": self.seeds_jitter,
        }


_BAR: list = [None]  # the progress bar of the command running (paper or robustness), advanced once per run


def _run(name, sets):
    scene = load_scene(name, list(sets))
    res = run_scene(scene, progress=False)
    if _BAR[0] is not None:
        _BAR[0].update(1)
    return scene, res, observables(res.t, res.alpha, res.beta)


def _walls_item(fig, what, z_source, obs_list):
    zs = [o["domain_walls"] for o in obs_list]
    hits = sum(z == z_source for z in zs)
    frac = hits / len(zs)
    lam = [o["pattern_wavelength_cells"] for o in obs_list]
    ours = lam[0] if len(lam) == 1 else {"fraction_selecting_source": frac, "lambda_cells": lam}
    return Item(
        fig,
        what,
        30 / z_source if z_source else None,
        ours,
        frac > 0.5,
        note=f"domain walls {zs}; source Z = {z_source}",
    )


def _rounded(intervals):
    """Unstable intervals' edges (cells) to two decimals for a note; open edges stay None."""
    return [[None if x is None else round(x, 2) for x in iv] for iv in intervals]


def fig2_theory(items: list[Item]) -> dict:
    """a.i-c.i: the regime of each sigma at the table k (as the source drew it) and at the rig's k, by the linear
    theory of the lattice with inertia (THEORY); the overdamped theory's regime in the note."""
    curves = {}
    for key, (label, sigma, src_text, regime) in SIGMAS.items():
        for bs, which in ((0.5, "table k"), (1.0, "rig k")):
            p = Params(sigma=sigma, band_scale=bs)
            d = dispersion(p, theory=THEORY, n_cells=16)
            c = dispersion(p, theory=Theory("lattice", THEORY.inertia, False), n_cells=None)
            over = dispersion(p, inertia=False)["regime"]
            curves[(key, bs)] = (d, c)
            items.append(
                Item(
                    f"2{key}.i",
                    f"regime at sigma = {label}, {which}",
                    regime,
                    d["regime"],
                    d["regime"] == regime,
                    note=f"source: {src_text}; ours without inertia: {over}; unstable "
                    f"{format_set(_rounded(d['unstable_set_cells']))} cells",
                )
            )
    return curves


def fig2_runs(items: list[Item]) -> dict[str, Any]:
    runs: dict[str, Any] = {}
    for key, (scene, sets, z) in FIG2_RUNS.items():
        sc, res, o = _run(scene, sets)
        runs[key] = (sc, res)
        items.append(_walls_item(f"2{key}.ii", f"pattern after one push on alpha_8, sigma = {SIGMAS[key][0]}", z, [o]))
        items[-1].check = SEED_CHECKS[f"2{key}.ii"]
    # c.ii: 14/125, eta x1 oscillates (actuator-limited lattice; hil with back-EMF compensation), eta x10 rests
    sc, res, o = _run("exp3_single_sigma14", ["model=lattice", "model_options.dt_out=0.002"])
    runs["c1"] = (sc, res)
    per = o["oscillation_period_s"]
    items.append(
        Item(
            "2c.ii",
            "oscillation period, sigma = 14/125, eta x1 (lattice, actuator limit)",
            SOURCE_PERIOD_S,
            per,
            per is not None and abs(per - SOURCE_PERIOD_S) <= PERIOD_TOL * SOURCE_PERIOD_S,
            note=f"dominant mode {o['dominant_mode']} (0 = uniform), amplitude {o['amplitude_rad']:.3f} rad",
            check=SEED_CHECKS["2c.ii lattice"],
        )
    )
    sc, res, o = _run("exp3_single_sigma14", ["params.bemf_comp=true"])
    runs["c1h"] = (sc, res)
    per = o["oscillation_period_s"]
    items.append(
        Item(
            "2c.ii",
            "oscillation period, sigma = 14/125, eta x1 (hil, back-EMF compensation on)",
            SOURCE_PERIOD_S,
            per,
            per is not None and abs(per - SOURCE_PERIOD_S) <= PERIOD_TOL * SOURCE_PERIOD_S,
            note="the firmware's velocity estimate sets this period (docs/band-stiffness.md)",
            check=SEED_CHECKS["2c.ii hil"],
        )
    )
    sc, res, o = _run("exp4_stable_eta10", [])
    runs["c10"] = (sc, res)
    items.append(
        Item(
            "exp. 4",
            "sigma = 14/125, eta x10: decays to rest (the source's text; no figure panel)",
            "rest",
            "rest" if o["at_rest"] else "moving",
            o["at_rest"],
            check=SEED_CHECKS["exp. 4"],
        )
    )
    return runs


def _noise_sets(seed):
    return [f"model_options.noise.seed={seed}"] + [f"model_options.noise.{k}={v}" for k, v in NOISE.items()]


def fig3_runs(items: list[Item], repeats: int) -> dict[str, Any]:
    runs: dict[str, Any] = {}
    for key, (scene, z) in FIG3_RUNS.items():
        obs, finals = [], []
        for r in range(repeats):
            sc, res, o = _run(scene, ["model=hil"] + _noise_sets(1000 + r))
            obs.append(o)
            finals.append(res.alpha[-1])
            if r == 0:
                runs[key] = (sc, res)
        runs[key + "_finals"] = np.array(finals)
        if z == 0:
            rest = sum(o["at_rest"] for o in obs) / len(obs)
            items.append(
                Item(f"3{key}", "no perturbation stays at rest", "rest", {"fraction_at_rest": rest}, rest == 1.0)
            )
        else:
            items.append(_walls_item(f"3{key}", f"pattern of {scene} ({repeats} noisy repeats)", z, obs))
        items[-1].check = SEED_CHECKS[f"3{key}"]
    return runs


def seed_checks(items: list[Item], seeds: int) -> None:
    """Each run item's fraction of `seeds` noise seeds (and of the same with encoder jitter) selecting the source's
    result (robustness.seed_fractions: its seeds, its noise, its agreement rule)."""
    from .robustness import seed_fractions

    for it in items:
        if it.check is None or seeds < 1:
            continue
        name, sets, want, jitter = it.check
        it.seeds, it.seeds_jitter = seed_fractions(name, sets, want, seeds, jitter=jitter)


def _seed_runs(seeds: int) -> int:
    return sum(seeds * (2 if jitter else 1) for _, _, _, jitter in SEED_CHECKS.values())


def seed_counts(doc: dict) -> dict:
    """What the seeds say, over the items that come from runs: how many every seed selects, most seeds (more than
    half), fewer; each for the plain noise and with encoder jitter (items run on the lattice have no jitter)."""
    out: dict = {}
    for key in ("seeds", "seeds_jitter"):
        fr = [i[key] for i in doc["items"] if i.get(key) is not None]
        out[key] = {
            "items": len(fr),
            "every_seed": sum(f == 1.0 for f in fr),
            "most_seeds": sum(0.5 < f < 1.0 for f in fr),
            "at_most_half": sum(f <= 0.5 for f in fr),
        }
    return out


# ---- figures ----------------------------------------------------------------------------------------
LAMBDA_TICKS = (2, 3, 5, 7.5, 10, 15, 30, 60)


def _figure(w, h):
    from matplotlib.figure import Figure

    return Figure(figsize=(w, h), constrained_layout=True)


def _panel_letter(ax, text: str) -> None:
    """The source's panel letter in the panel's top-left corner, as the source labels its panels."""
    ax.text(
        0.02,
        0.97,
        text,
        transform=ax.transAxes,
        fontsize=11,
        fontweight="bold",
        va="top",
        bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1.5},
    )


def draw_fig2_theory(curves: dict, path: Path) -> None:
    """Fig. 2 a.i-c.i: absolute growth rate Re s (1/s) against wavelength, linear theory of the lattice with inertia
    (THEORY), at the table k and at the rig's k: the continuum as a curve, the 16-cell chain's modes as markers, the
    oscillatory unstable intervals hatched."""
    from matplotlib.ticker import NullFormatter

    fig = _figure(13, 3.9)
    fig.suptitle(f"Fig. 2 a.i-c.i: growth rate of each mode, linear theory of the {THEORY.label()}", fontsize=10)
    for i, (key, (label, _, _, _)) in enumerate(SIGMAS.items()):
        ax = fig.add_subplot(1, 3, i + 1)
        for bs, ls, which in ((0.5, "-", "table k"), (1.0, "--", "rig k")):
            d, c = curves[(key, bs)]
            colour = "C0" if bs == 0.5 else "C1"
            ax.plot(
                c["curve"]["lambda_cells"],
                c["curve"]["growth_per_s"],
                ls,
                color=colour,
                lw=1,
                label=f"continuum, {which}",
            )
            modes = [m for m in d["lattice_modes"] if m["lambda_cells"]]
            ax.plot(
                [m["lambda_cells"] for m in modes],
                [m["growth_per_s"] for m in modes],
                "o" if bs == 0.5 else "s",
                ms=3.5,
                mfc="none",
                color=colour,
                label=f"16-cell modes, {which}",
            )
            for iv in d["unstable_intervals"]:
                if iv["kind"] == "oscillatory":
                    lo, hi = iv["lambda_cells"]
                    ax.axvspan(lo, hi or 1e3, color=colour, alpha=0.08, hatch="//" if bs == 0.5 else "\\\\", lw=0)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xscale("log")
        ax.set_xlim(1.8, 60)
        ax.set_xticks(LAMBDA_TICKS, [f"{v:g}" for v in LAMBDA_TICKS])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(-80, 60)
        ax.set_xlabel("wavelength (cells)")
        ax.set_ylabel("growth rate Re s (1/s)")
        d = curves[(key, 1.0)][0]
        ax.set_title(f"sigma = {label}: {d['regime'].replace('_', ' ')}", fontsize=9)
        _panel_letter(ax, f"{key}.i")
        ax.legend(fontsize=6, loc="lower right", title="hatched: oscillatory, grows", title_fontsize=6)
    fig.savefig(path, dpi=110)


def _spacetime(ax, res, title):
    lim = float(np.abs(res.alpha).max()) or 1.0
    n = res.alpha.shape[1]
    im = ax.imshow(
        res.alpha.T,
        aspect="auto",
        origin="lower",
        cmap="RdBu_r",
        vmin=-lim,
        vmax=lim,
        extent=(res.t[0], res.t[-1], 0.5, n + 0.5),
        interpolation="nearest",
    )
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("cell j")
    cell_ticks(ax.yaxis, n)
    return im


def draw_fig2_runs(runs: dict[str, Any], path: Path) -> None:
    """Fig. 2 a.ii-c.ii (one push on alpha_8 at 9/125, 6/125, 14/125) and experiment 4 (14/125, eta x10, which the
    source describes in its text without a panel)."""
    fig = _figure(15, 3.6)
    panels = [
        ("a", "a.ii", "sigma 9/125"),
        ("b", "b.ii", "sigma 6/125"),
        ("c1", "c.ii", "sigma 14/125, eta x1 (lattice), first 0.5 s"),
        ("c10", "exp. 4", "sigma 14/125, eta x10 (no panel in the source)"),
    ]
    for i, (k, letter, title) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), i + 1)
        sc, res = runs[k]
        im = _spacetime(ax, res, f"{title}\n{sc.name} ({sc.model})")
        if k == "c1":
            ax.set_xlim(0, 0.5)
        _panel_letter(ax, letter)
        fig.colorbar(im, ax=ax, label="alpha (rad)")
    fig.suptitle("Fig. 2 a.ii-c.ii: space-time maps of alpha after one push on alpha_8", fontsize=10)
    fig.savefig(path, dpi=110)


def draw_fig3(runs: dict[str, Any], path: Path) -> None:
    """Fig. 3 a-c: the final alpha profile of each loading, the mean of the noisy hil repeats with the min..max
    spread over them as error bars (said in the legend)."""
    fig = _figure(13, 3.8)
    for i, (key, (scene, z)) in enumerate(FIG3_RUNS.items()):
        ax = fig.add_subplot(1, 3, i + 1)
        finals = runs[key + "_finals"]
        j = np.arange(1, finals.shape[1] + 1)
        mean = finals.mean(axis=0)
        ax.errorbar(
            j,
            mean,
            yerr=[np.clip(mean - finals.min(axis=0), 0, None), np.clip(finals.max(axis=0) - mean, 0, None)],
            fmt="o-",
            ms=3,
            capsize=2,
            label=f"mean of {len(finals)} repeats (hil, 5 % spread)\nbars: min..max over the repeats",
        )
        ax.axhline(0, color="0.6", lw=0.6)
        ax.set_ylim(-1.2, 1.2)
        ax.set_xlabel("cell j")
        cell_ticks(ax.xaxis, finals.shape[1])
        ax.set_ylabel("final alpha (rad)")
        ax.set_title(f"{scene}: source {'lambda = ' + format(30 / z, 'g') if z else 'rest'}", fontsize=9)
        _panel_letter(ax, key)
        ax.legend(fontsize=6, loc="lower left")
    fig.suptitle(
        "Fig. 3 a-c: final alpha profiles: (a) no push, (b) CCW-CCW on 6 and 10, (c) CCW-CW on 1 and 16", fontsize=10
    )
    fig.savefig(path, dpi=110)


def build(out: Path, repeats: int = 10, *, seeds: int = 0, quiet: bool = False) -> dict:
    """Run every item, check each run item over `seeds` noise seeds (0, the default here: no check; the command's
    default is DEFAULT_SEEDS), draw the figures into out/, write out/paper.json; returns its content. A progress bar
    (one step per run) on a terminal unless quiet."""
    t0 = time.perf_counter()
    items: list[Item] = []
    curves = fig2_theory(items)
    total = len(FIG2_RUNS) + 3 + len(FIG3_RUNS) * repeats + _seed_runs(seeds)
    _BAR[0] = bar(total, desc="paper", unit="run", quiet=quiet)
    try:
        runs2 = fig2_runs(items)
        runs3 = fig3_runs(items, repeats)
        seed_checks(items, seeds)
    finally:
        _BAR[0].close()
        _BAR[0] = None
    out.mkdir(parents=True, exist_ok=True)
    files = ["fig2_dispersion.png", "fig2_spacetime.png", "fig3_patterns.png"]
    draw_fig2_theory(curves, out / files[0])
    draw_fig2_runs(runs2, out / files[1])
    draw_fig3(runs3, out / files[2])
    doc = {
        "items": [i.as_dict() for i in items],
        "agree": sum(i.agree for i in items),
        "total": len(items),
        "repeats": repeats,
        "seeds": seeds,
        "noise": NOISE,
        "period_tolerance": PERIOD_TOL,
        "files": files,
        "wall_s": time.perf_counter() - t0,
    }
    doc["seed_counts"] = seed_counts(doc)
    (out / "paper.json").write_text(json.dumps(doc, indent=2, default=_json_default) + "\n")
    return doc


def paper_budget(repeats: int, seeds: int = DEFAULT_SEEDS) -> str | None:
    """The runs of `paper` (Fig. 2's five, Fig. 3's three panels x repeats, each run item's seeds) against the batch
    limit."""
    runs = [(s, sets) for s, sets, _ in FIG2_RUNS.values()] + [  # as fig2_runs runs them
        ("exp3_single_sigma14", ["model=lattice", "model_options.dt_out=0.002"]),
        ("exp3_single_sigma14", ["params.bemf_comp=true"]),
        ("exp4_stable_eta10", []),
    ]
    fixed = sum(scene_cost(load_scene(n, sets)) for n, sets in runs)
    per = sum(scene_cost(load_scene(n, ["model=hil"])) for n, _ in FIG3_RUNS.values())
    checks = sum(
        seeds * (2 if jitter else 1) * scene_cost(load_scene(n, sets)) for n, sets, _, jitter in SEED_CHECKS.values()
    )
    return batch_budget(fixed + repeats * per + checks, f"paper --repeats {repeats} --seeds {seeds}")


def _json_default(v):
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    raise TypeError(type(v))


def _short(v):
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k}={_short(x)}" for k, x in v.items())
    if isinstance(v, list):
        return "[" + ", ".join(_short(x) for x in v[:10]) + ("..." if len(v) > 10 else "") + "]"
    return str(v)


def aligned(rows: list[list[str]], header: list[str], right: Sequence[int] = ()) -> list[str]:
    """Rows of cells as lines of columns padded to their widest cell (right-aligned for the indices in right)."""
    widths = [max(len(str(r[k])) for r in [header, *rows]) for k in range(len(header))]

    def line(r):
        return "  ".join(
            f"{str(c):>{w}}" if k in right else f"{str(c):<{w}}" for k, (c, w) in enumerate(zip(r, widths))
        )

    return [line(header), "  ".join("-" * w for w in widths)] + [line(r).rstrip() for r in rows]


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.0f} %"


def print_table(doc: dict, file: TextIO = sys.stdout) -> None:
    seeds = doc.get("seeds", 0)
    rows = [
        [i["figure"], i["item"], _short(i["source"]), _short(i["ours"]), "yes" if i["agree"] else "NO"]
        + ([_pct(i.get("seeds")), _pct(i.get("seeds_jitter"))] if seeds else [])
        for i in doc["items"]
    ]
    header = ["fig", "item", "source", "ours", "agree"] + (["seeds", "+jitter"] if seeds else [])
    for ln in aligned(rows, header, right=(5, 6) if seeds else ()):
        print(ln, file=file)
    print(
        "legend: fig = the source's panel (exp. 4: its text, no panel); source = its number or classification in our "
        "regime names;\n        ours = the emulator's (a fraction: of the noisy repeats); agree = the rule in "
        "host_emulator/workbench/paper.py (walls equal; period within 10 %; regimes equal; rest).",
        file=file,
    )
    if seeds:
        print(
            f"        seeds = the fraction of {seeds} noise seeds (5 % spread of band stiffness and honey viscosity) "
            "whose run selects the source's result;\n        +jitter = the same with 0.5 count rms encoder jitter "
            "(hil runs); as `robustness --seeds N` counts them (- : a theory item, or no jitter on the lattice).",
            file=file,
        )
    print(f"{doc['agree']} of {doc['total']} items agree ({doc['repeats']} repeats, {doc['wall_s']:.1f} s)", file=file)
    if seeds:
        print(seeds_line(doc), file=file)


def seeds_line(doc: dict) -> str:
    """The summary of what the seeds say (seed_counts), naming the items that fewer than every seed select."""
    c = doc["seed_counts"]

    def counts(k: str) -> str:
        n = c[k]
        return (
            f"every seed selects it in {n['every_seed']}, most seeds in {n['most_seeds']}, "
            f"half or fewer in {n['at_most_half']}"
        )

    weak = [
        f"{i['figure']} {_pct(i['seeds'])}"
        + (f" ({_pct(i['seeds_jitter'])} with jitter)" if i["seeds_jitter"] is not None else "")
        for i in doc["items"]
        if i.get("seeds") is not None
        and (i["seeds"] < 1.0 or (i["seeds_jitter"] is not None and i["seeds_jitter"] < 1.0))
    ]
    return (
        f"over {doc['seeds']} noise seeds, of the {c['seeds']['items']} items from runs: {counts('seeds')}; "
        f"with encoder jitter, of {c['seeds_jitter']['items']}: {counts('seeds_jitter')}"
        + (f"\nbelow every seed: {', '.join(weak)}" if weak else "")
    )


def paper_main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator paper",
        description="Regenerate the source paper's Fig. 2 and Fig. 3 and compare item by item.",
        epilog="example: python -m host_emulator paper --out out/paper --repeats 10 --seeds 20",
    )
    ap.add_argument("--out", default="out/paper", help="output directory (default out/paper)")
    ap.add_argument(
        "--repeats", type=int, default=10, help="noisy hil repeats per Fig. 3 panel (default 10, as the rig)"
    )
    ap.add_argument(
        "--seeds",
        type=int,
        default=DEFAULT_SEEDS,
        help=f"noise seeds checking each run item, as `robustness` (default {DEFAULT_SEEDS}; 0: no check)",
    )
    ap.add_argument("--quiet", action="store_true", help="no progress bar (it shows on a terminal only anyway)")
    args = ap.parse_args(argv)
    if not 1 <= args.repeats <= 1000:
        print(f"paper: error: --repeats {args.repeats}: must be in 1..1000", file=sys.stderr)
        return 2
    if not 0 <= args.seeds <= 10000:
        print(f"paper: error: --seeds {args.seeds}: must be in 0..10000", file=sys.stderr)
        return 2
    out = Path(args.out)
    problem = check_out_dir(out) or paper_budget(args.repeats, args.seeds)
    if problem:
        print(f"paper: error: {problem}", file=sys.stderr)
        return 2
    doc = build(out, args.repeats, seeds=args.seeds, quiet=args.quiet)
    print_table(doc)
    print(f"wrote {out}/paper.json, " + ", ".join(f"{out}/{f}" for f in doc["files"]))
    return 0 if doc["agree"] == doc["total"] else 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(paper_main(sys.argv[1:]))
