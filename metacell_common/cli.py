"""What every command line shares: the last guard's one-line error (unexpected) and cell lists in messages."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable


def unexpected(e: BaseException, prog: str) -> int:
    """An error no check foresaw (a numerical library's LinAlgError, an OS error of a dependency...): one line
    naming it, exit 3; the traceback only with MC_DEBUG=1."""
    if os.environ.get("MC_DEBUG"):
        raise e
    from numpy.linalg import LinAlgError

    what = "numerical failure" if isinstance(e, (ArithmeticError, LinAlgError)) else "run failed"
    text = " ".join(str(e).split()) or "(no message)"
    print(f"{prog}: error: {what}: {type(e).__name__}: {text[:300]} (MC_DEBUG=1 shows the traceback)", file=sys.stderr)
    return 3


def cells_text(cells: Iterable[int]) -> str:
    """[1, 2, 3, 5] -> '1-3, 5'."""
    out: list[str] = []
    run: list[int] = []
    for j in sorted(cells):
        if run and j == run[-1] + 1:
            run.append(j)
            continue
        if run:
            out.append(f"{run[0]}-{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
        run = [j]
    if run:
        out.append(f"{run[0]}-{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
    return ", ".join(out)
