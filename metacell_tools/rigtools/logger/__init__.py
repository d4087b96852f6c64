"""Rig logger on python-can: log files, decoded alpha_j(t)/beta_j(t) arrays (NPZ, CSV), gap reports, reconnects.

    python -m metacell_tools.rigtools.logger -c /dev/ttyACM0@115200 -o out/run1 --duration 60
    python -m metacell_tools.rigtools.logger -c /dev/pts/3@115200 -o out/emu --formats asc,blf

Writes <out>.<fmt> for every python-can format asked for (asc blf csv db log trc txt),
<out>.csv (one row per cell sample, on disk within 1.5 s of its frame) and, at the end,
<out>.npz (the one run layout host_emulator.load reads, time x cell with a `partial` flag
per cycle; written to a temporary name and renamed; see docs/datapath.md).
An --out that already holds a capture (its CSV has a row, its NPZ a sample) is refused, exit 2 and nothing
changed, unless --overwrite is given (which removes the old capture's files first); a capture put right by
--repair is one too. `--repair PREFIX` puts the files of a killed or full-disk run right (BLF cut to its last
object, NPZ rebuilt from the CSV). A port another program holds is refused. Every gap in a cell's
sequence counter is reported on stderr with its length as it happens and kept in the NPZ;
a link silent for more than a second is reported; a lost connection is reported, retried
every second, and logged as a new segment. --duration counts from the first frame.

Ctrl-C, SIGTERM and SIGHUP end the run in order (files complete, exit 0); a full disk
ends it with a one-line error and files readable up to the last complete record.
Exit codes: 0 ok, 2 bad input (arguments, output path), 3 run failed (port cannot be
opened, no frame arrives, write error).

The package by responsibility: the capture decoder is protocol.capture (he.load reads python-can logs and logger
CSVs with it); `files` the NPZ, the streamed CSV and --repair; `live` the receive loop (RigLogger); `cli` the command
line. Every name the logger module had is importable from here.
"""

from protocol.capture import (
    CSV_HEADER,
    T128_S,
    T_WRAP,
    format_rows,
    gaps_from_rows,
    partial_cycles,
    read_rows,
    reset_cause_names,
    rows_to_arrays,
)
from protocol.codec import RAD_PER_COUNT

from .cli import check_out, held_capture, main
from .files import (
    BLF_HEADER,
    BLF_OBJ,
    TEXT_FORMATS,
    CsvChunks,
    RunFailed,
    SampleDecoder,
    flush_writer,
    repair,
    repair_blf,
    truncate_to_last_line,
    write_capture,
)
from .live import RigLogger, channel_source

__all__ = [
    "BLF_HEADER",
    "BLF_OBJ",
    "CSV_HEADER",
    "RAD_PER_COUNT",
    "T128_S",
    "TEXT_FORMATS",
    "T_WRAP",
    "CsvChunks",
    "RigLogger",
    "RunFailed",
    "SampleDecoder",
    "channel_source",
    "check_out",
    "held_capture",
    "flush_writer",
    "format_rows",
    "gaps_from_rows",
    "main",
    "partial_cycles",
    "read_rows",
    "repair",
    "repair_blf",
    "reset_cause_names",
    "rows_to_arrays",
    "truncate_to_last_line",
    "write_capture",
]
