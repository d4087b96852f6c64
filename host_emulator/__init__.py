"""Host emulator of the pattern-forming robotic metamaterial: the shipped firmware against a simulated plant.

Python API (imports are lazy, so ``import host_emulator`` is cheap)::

    import host_emulator as he
    r = he.run("default", overrides={"params.sigma": 0.05})   # RunResult: time, alpha, beta, summary
    r.to_xarray()                                              # xarray.Dataset, dims (time, cell)
    ds = he.load("out/rig1")        # any run or capture, rig or emulated, in the same Dataset layout
    he.plot_spacetime(r)                                       # a matplotlib Figure (a sheet: its snapshots)
    he.plot_snapshots(r, times=[0.1, 0.5])                     # a 2-D sheet's alpha at a few times
    he.sweep("default", {"params.sigma": [0.05, 0.07]}, seeds=2, out="out/sw")   # xarray.Dataset
    d = he.design("lambda=10", push="8", out="out/d")   # parameters for a target pattern (design.json's content)
    he.runs("out")                  # pandas table of every run and capture under a folder
"""

__all__ = [
    "run",
    "RunResult",
    "load_scene",
    "list_scenes",
    "sweep",
    "design",
    "load",
    "runs",
    "plot_spacetime",
    "plot_final",
    "plot_snapshots",
    "plot_dispersion",
    "plot_phase_diagram",
    "plot_regime_map",
    "__version__",
]

# API name -> the workbench module that holds it (host_emulator/workbench/); no module of the package has the
# name of an API function, so `he.sweep` is the function however often it is called or imported
_LAZY = {
    "run": "workbench.api",
    "RunResult": "workbench.api",
    "load_scene": "workbench.api",
    "list_scenes": "workbench.api",
    "plot_spacetime": "workbench.plots",
    "plot_final": "workbench.plots",
    "plot_snapshots": "workbench.sheet_plots",
    "plot_dispersion": "workbench.plots",
    "sweep": "workbench.sweep",
    "design": "workbench.design",
    "load": "workbench.datasets",
    "runs": "workbench.catalogue",
    "plot_phase_diagram": "workbench.sweep",
    "plot_regime_map": "workbench.sweep",
}


def __getattr__(name):
    if name == "__version__":
        try:
            from importlib.metadata import version

            return version("metamaterial-rig")
        except Exception:  # noqa: BLE001 - not installed (a bare checkout)
            return "0+unknown"
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value  # bound once: later calls find the function, never a submodule of the same name
        return value
    raise AttributeError(f"module 'host_emulator' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
