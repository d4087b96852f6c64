"""The cross binutils (Debian gcc-arm-none-eabi) the target analyses run: one call, its output, ToolError otherwise."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


class ToolError(RuntimeError):
    """A cross tool is missing or failed; the message names it."""


def run(cmd: list[str], cwd: Path | None = None) -> str:
    """Run a cross tool; its stdout, or ToolError naming what is missing or what failed."""
    if shutil.which(cmd[0]) is None:
        raise ToolError(f"{cmd[0]} not found: run tools/setup.sh (Debian gcc-arm-none-eabi)")
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        raise ToolError(f"{' '.join(cmd)} failed:\n{p.stdout}{p.stderr}")
    return p.stdout
