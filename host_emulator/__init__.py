"""Host emulator of the pattern-forming robotic metamaterial: the shipped firmware against a simulated plant.

Python API (imports are lazy, so ``import host_emulator`` is cheap)::

    import host_emulator as he
    r = he.run("default", overrides={"params.sigma": 0.05})   # RunResult: time, alpha, beta, summary
    r.to_xarray()                                              # xarray.Dataset, dims (time, cell)
    ds = he.load("out/rig1")        # any run or capture, rig or emulated, in the same Dataset layout
    he.plot_spacetime(r)                                       # a matplotlib Figure
    he.sweep("default", {"params.sigma": [0.05, 0.07]}, seeds=2, out="out/sw")   # xarray.Dataset
"""

__all__ = [
    "run",
    "RunResult",
    "load_scene",
    "list_scenes",
    "sweep",
    "load",
    "plot_spacetime",
    "plot_final",
    "plot_dispersion",
    "plot_phase_diagram",
    "plot_regime_map",
    "provenance",
    "__version__",
]

_LAZY = {
    "run": "api",
    "RunResult": "api",
    "load_scene": "api",
    "list_scenes": "api",
    "plot_spacetime": "plots",
    "plot_final": "plots",
    "plot_dispersion": "plots",
    "sweep": "sweep",
    "load": "datasets",
    "plot_phase_diagram": "sweep",
    "plot_regime_map": "sweep",
    "provenance": "provenance",
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
