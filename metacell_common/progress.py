"""Progress bars (tqdm) for every command that can take more than a few seconds: on stderr, shown on a terminal
only (never in a pipe, a log file or a test), off under --quiet."""

from __future__ import annotations

import sys
from typing import Any, TextIO


def bar(
    total: float | None = None,
    *,
    desc: str,
    unit: str = "it",
    quiet: bool = False,
    file: TextIO | None = None,
    **kw: Any,
):
    """A tqdm bar: disabled when quiet, else tqdm's own rule (disable=None: off when the stream is not a TTY)."""
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        disable=True if quiet else None,
        file=file or sys.stderr,
        dynamic_ncols=True,
        **kw,
    )
