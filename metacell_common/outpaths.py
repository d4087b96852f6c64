"""Output paths checked and created before any work: every command's --out, --plot, --json, --link, --live-png.

Each check returns why the path cannot be written, as one line naming the option, or None. It creates the
directory (and, for a file, probes it by creating it, or opening an existing one for append, which changes
nothing), so a read-only place, a path through a file, a name too long for the file system or a full directory
fails here, before the simulation, and never after it as a traceback. A command rejected after its checks (exit
2) calls remove_created_since, so a rejection leaves no empty directory behind. `os.access` alone is not enough: it says
yes to root on a read-only mount and knows nothing of name lengths.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

SHOW = 80  # characters of a path shown in a message (an over-long path stays one short line)
_CREATED: list[Path] = []  # directories these checks created in this process, in the order they were made


def created_mark() -> int:
    """A mark for remove_created_since: a command takes one before its checks."""
    return len(_CREATED)


def remove_created_since(mark: int) -> None:
    """A rejection leaves nothing behind: the directories the checks created since mark that are still empty are
    removed (deepest first); a directory that holds anything, or existed before, is left alone."""
    for d in reversed(_CREATED[mark:]):
        try:
            d.rmdir()
        except OSError:
            pass
    del _CREATED[mark:]


def _mkdir(p: Path) -> None:
    """p.mkdir(parents=True, exist_ok=True), remembering the directories it made (remove_created_since)."""
    missing = []
    q = p
    while not q.exists() and q != q.parent:
        missing.append(q)
        q = q.parent
    p.mkdir(parents=True, exist_ok=True)
    _CREATED.extend(reversed(missing))


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
        _mkdir(p)
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
        _mkdir(p.parent)
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
