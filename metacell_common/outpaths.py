"""Output paths checked and created before any work: every command's --out, --plot, --json, --link, --live-png.

Each check returns why the path cannot be written, as one line naming the option, or None. It creates the
directory (and, for a file, probes it by creating it, or opening an existing one for append, which changes
nothing), so a read-only place, a path through a file, a name too long for the file system or a full directory
fails here, before the simulation, and never after it as a traceback. `os.access` alone is not enough: it says
yes to root on a read-only mount and knows nothing of name lengths.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

SHOW = 80  # characters of a path shown in a message (an over-long path stays one short line)


def show(path: str | os.PathLike) -> str:
    text = os.fspath(path)
    return text if len(text) <= SHOW else f"{text[:40]}...{text[-30:]} ({len(text)} characters)"


def _why(e: OSError) -> str:
    return e.strerror or str(e)


def check_out_dir(path: str | os.PathLike, opt: str = "--out") -> str | None:
    """Create the output directory now and prove a file can be made in it; why not (one line), or None."""
    p = Path(path)
    try:
        if p.exists() and not p.is_dir():
            return f"{opt} {show(p)}: exists and is not a directory"
        p.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=p, prefix=".write-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        return f"{opt} {show(p)}: cannot create or write it: {_why(e)}"
    return None


def check_out_file(path: str | os.PathLike, opt: str, suffixes: tuple[str, ...] = ()) -> str | None:
    """Create the file's directory and prove the file can be written (created then removed, or an existing file
    opened for append); why not (one line), or None. suffixes: accepted endings, e.g. (".png",)."""
    p = Path(path)
    if suffixes and not p.name.lower().endswith(suffixes):
        return f"{opt} {show(p)}: expected a {' or '.join(suffixes)} file"
    try:
        if p.is_dir():
            return f"{opt} {show(p)}: is a directory"
        p.parent.mkdir(parents=True, exist_ok=True)
        existed = p.exists()
        with open(p, "ab"):
            pass
        if not existed:
            os.unlink(p)
    except OSError as e:
        return f"{opt} {show(p)}: cannot create or write it: {_why(e)}"
    return None


def first_problem(*problems: str | None) -> str | None:
    return next((p for p in problems if p), None)
