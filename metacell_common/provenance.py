"""Provenance: which code, libraries and command produced an output (summary.json, NetCDF attributes, sweeps).

``provenance()`` returns a flat dict of strings, safe as NetCDF attributes and JSON:

* package_version: the installed distribution's version (metamaterial-rig);
* git_describe: ``git describe --always --dirty --tags`` of the source tree ("unknown" outside a checkout);
* firmware_build: the hash of the firmware library and emulator C sources the emulator compiled
  (the same key that names the build directory, build/host/<hash>);
* python, numpy, scipy, python_can (and xarray, dask when installed) versions;
* created_utc: ISO 8601 time of the call; command: the command line (sys.argv joined, shell-quoted).

``machine()`` names the machine a timing was taken on (CPU model, cores, load average, date): every speed
figure the benchmarks print carries it, since absolute times do not transfer between machines.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import shlex
import subprocess
import sys
from collections.abc import Sequence
from functools import lru_cache
from importlib.metadata import version
from pathlib import Path

from . import firmware

ROOT = Path(__file__).resolve().parents[1]


@lru_cache(maxsize=1)
def git_describe() -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "describe", "--always", "--dirty", "--tags"],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else "unknown"


@lru_cache(maxsize=1)
def firmware_build() -> str:
    """Hash of the firmware + emulator C sources (the build key, once per process: the library a process loads
    does not change under it); "unknown" if the sources are not present."""
    try:
        return firmware._digest(firmware._sources() + firmware._headers())
    except Exception:  # noqa: BLE001 - provenance must never break an output
        return "unknown"


def _version(mod: str) -> str:
    try:
        return version(mod)
    except Exception:  # noqa: BLE001
        return "not installed"


@lru_cache(maxsize=1)
def _static() -> dict:
    return {
        "package_version": _version("metamaterial-rig"),
        "git_describe": git_describe(),
        "python": sys.version.split()[0],
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "python_can": _version("python-can"),
        "xarray": _version("xarray"),
        "dask": _version("dask"),
    }


def provenance(command: Sequence[str] | None = None) -> dict:
    """Flat dict of strings naming the code version, library versions, UTC time and command line."""
    argv = sys.argv if command is None else command
    return {
        **_static(),
        "firmware_build": firmware_build(),
        "created_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "command": argv if isinstance(argv, str) else shlex.join(str(a) for a in argv),
    }


@lru_cache(maxsize=1)
def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux), else what platform knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def machine() -> dict:
    """CPU model, logical cores, 1/5/15-minute load average (None where the OS has none) and today's UTC date."""
    try:
        load: list[float] | None = [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        load = None
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count() or 0,
        "load": load,
        "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d"),
    }


def machine_line() -> str:
    """machine() as one line: 'AMD EPYC, 2 cores, load 1.2/1.0/0.8, 2026-11-23'."""
    m = machine()
    load = "/".join(f"{x:.1f}" for x in m["load"]) if m["load"] else "unknown"
    return f"{m['cpu']}, {m['cores']} cores, load {load}, {m['date']}"
