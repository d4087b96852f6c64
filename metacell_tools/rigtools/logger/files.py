"""The logger's files: the NPZ in the one run layout (write_capture), the streamed CSV (CsvChunks), the decoder that
saves both (SampleDecoder), and the repair of a killed or full-disk run's files (--repair: text logs and the CSV cut
after their last complete line, the BLF after its last complete object, the NPZ rebuilt from the CSV)."""

from __future__ import annotations

import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path

from can.io.blf import FILE_HEADER_STRUCT

from metacell_common.provenance import provenance
from metacell_common.runlayout import logger_layout, write_npz
from protocol import capture
from protocol.capture import CSV_HEADER, format_rows, gaps_from_rows, read_rows, rows_to_arrays
from protocol.wire import N_CELLS

TEXT_FORMATS = ("asc", "csv", "log", "txt", "trc")


class RunFailed(Exception):
    """The run could not go on (exit 3); the message is one line."""


class SampleDecoder(capture.SampleDecoder):
    """protocol.capture.SampleDecoder (CELL_SAMPLE frames -> per-cycle rows, gaps), which also saves what it holds as
    the logger does: <prefix>.npz in the one run layout and <prefix>.csv (the experiment runner's repeats)."""

    def save(self, prefix: Path, attrs: dict | None = None) -> list[Path]:
        """<prefix>.npz in the one run layout (host_emulator.workbench.datasets; attrs: source, ...), <prefix>.csv."""
        prefix = Path(prefix)
        prefix.parent.mkdir(parents=True, exist_ok=True)
        arr = self.arrays()
        npz = write_capture(prefix.with_suffix(".npz"), arr, attrs or {})
        csv = prefix.with_suffix(".csv")
        with open(csv, "w") as f:
            f.write(CSV_HEADER)
            f.write(format_rows(self.rows))
        return [npz, csv]


def write_capture(path: Path, arr: dict, attrs: dict) -> Path:
    """Cycle x cell arrays (rows_to_arrays) as an NPZ in the one run layout of host_emulator.workbench.datasets:
    time from the first sample, alpha/beta in rad (NaN: no sample), flags, counts, each cell's primary clock, host
    time, cycles, segments, partial cycles, gaps; attrs (source, capture, channel, ...) with units and provenance;
    written to a temporary name and renamed (metacell_common.runlayout.save_npz_atomic). he.load reads it."""
    lay = logger_layout(arr)
    meta = {"source": "unknown", **attrs, "t_origin_s": lay.pop("t_origin_s")}
    meta.update({f"provenance.{k}": v for k, v in provenance().items()})
    return write_npz(path, lay, meta)


class CsvChunks:
    """Rows streamed to <out>.csv in chunks: memory stays bounded, and a chunk is written (to the OS) once it holds
    CHUNK rows or its oldest row has waited FLUSH_S (tick() is called by the receive loop, frames or not), so a
    killed logger loses only the rows of the last FLUSH_S plus those still held for a heartbeat (HOLD_S)."""

    CHUNK = 2048
    FLUSH_S = 0.25

    def __init__(self, path: Path) -> None:
        self.path = path
        self.f = open(path, "w")
        self.f.write(CSV_HEADER)
        self.f.flush()
        self.buf: list[tuple] = []
        self.since: float | None = None  # monotonic time the oldest buffered row arrived here

    def __call__(self, rows):
        if rows and not self.buf:
            self.since = time.monotonic()
        self.buf.extend(rows)
        if len(self.buf) >= self.CHUNK:
            self.write()

    def tick(self) -> None:
        if self.buf and self.since is not None and time.monotonic() - self.since >= self.FLUSH_S:
            self.write()

    def write(self) -> None:
        if self.buf:
            text = format_rows(self.buf)
            self.buf = []
            self.since = None
            self.f.write(text)
            self.f.flush()

    def close(self) -> None:
        try:
            self.write()
        finally:
            try:
                self.f.close()
            except OSError:
                pass


def truncate_to_last_line(path: Path) -> None:
    """Cut a text log after its last complete line (a write error may leave half a line)."""
    try:
        size = path.stat().st_size
        with open(path, "rb+") as f:
            back = min(size, 4096)
            while back:
                f.seek(size - back)
                tail = f.read(back)
                i = tail.rfind(b"\n")
                if i >= 0:
                    f.truncate(size - back + i + 1)
                    return
                if back == size:
                    break
                back = min(size, back * 2)
            f.truncate(0)
    except OSError:
        pass


def flush_writer(w) -> None:
    """Push a python-can writer's buffered data to the OS: BLF's pending container (a private method of
    BLFWriter, guarded), then the file object. Errors surface at stop()."""
    try:
        if hasattr(w, "_flush") and type(w).__name__ == "BLFWriter":
            w._flush()
        f = getattr(w, "file", None)
        if f is not None and not f.closed:
            f.flush()
    except (OSError, ValueError):
        pass  # reported by stop() at the end


BLF_HEADER = 144  # python-can's FILE_HEADER_SIZE
BLF_OBJ = struct.Struct("<4sHHLL")  # signature "LOBJ", header size, version, object size, type


def repair_blf(path: Path) -> tuple[int, int] | None:
    """Truncate a BLF to its last complete object and rewrite its header so python-can's BLFReader reads it
    (a killed logger leaves a cut container, or a file shorter than its header). Returns (bytes before, after)
    when it changed the file, None when the file was sound or absent."""
    try:
        size = path.stat().st_size
    except OSError:
        return None
    with open(path, "rb+") as f:
        head = f.read(BLF_HEADER)
        if len(head) < BLF_HEADER or head[:4] != b"LOGG":
            f.seek(0)
            f.truncate(0)
            _blf_header(f, None, BLF_HEADER)
            return size, BLF_HEADER
        pos = BLF_HEADER
        while pos + BLF_OBJ.size <= size:
            f.seek(pos)
            sig, _, _, obj_size, _ = BLF_OBJ.unpack(f.read(BLF_OBJ.size))
            end = pos + obj_size + obj_size % 4
            if sig != b"LOBJ" or obj_size < BLF_OBJ.size or end > size:
                break
            pos = end
        header = FILE_HEADER_STRUCT.unpack(head[: FILE_HEADER_STRUCT.size])
        if pos == size and header[10] == size:
            return None
        f.truncate(pos)
        _blf_header(f, header, pos)
    return size, pos


def _blf_header(f, header, filesize: int) -> None:
    if header is None:  # python-can's defaults (BLFWriter._write_header) with no objects
        fields = [b"LOGG", BLF_HEADER, 5, 0, 0, 0, 2, 6, 8, 1, filesize, BLF_HEADER, 0, 0] + [0] * 16
    else:
        fields = list(header)
        fields[10] = filesize
    f.seek(0)
    f.write(FILE_HEADER_STRUCT.pack(*fields))
    f.write(b"\x00" * (BLF_HEADER - FILE_HEADER_STRUCT.size))


def repair(
    prefix: Path,
    n_cells: int = N_CELLS,
    report: Callable[[str], None] | None = None,
    source: str | None = None,
    topology: dict | None = None,
) -> dict:
    """After a crash, a kill or a full disk: cut the text logs (and the CSV) after their last complete line, cut the
    BLF after its last complete object, and rebuild <prefix>.npz from the CSV (gaps from the cycle counters) in the
    one run layout (write_capture), labelled source (default unknown: the CSV does not say what sent the frames).
    topology: the rig config's (a sheet), written into the NPZ's attrs. Returns the logger's cycle x cell arrays the
    NPZ was made from."""
    report = report or (lambda text: print(text, file=sys.stderr, flush=True))
    prefix = Path(prefix)
    csv = prefix.with_suffix(".csv")
    if not csv.is_file():
        raise RunFailed(f"--repair {prefix}: {csv} not found (the logger's CSV is what the NPZ is rebuilt from)")
    for f in TEXT_FORMATS:
        p = prefix.with_suffix("." + f)
        if p.is_file():
            truncate_to_last_line(p)
    blf = repair_blf(prefix.with_suffix(".blf"))
    if blf:
        report(f"{prefix.with_suffix('.blf')}: cut from {blf[0]} to {blf[1]} bytes (last complete object)")
    try:
        rows = read_rows(csv, n_cells)
    except ValueError as e:
        raise RunFailed(f"--repair {prefix}: {csv} is not the logger's CSV: {e}") from None
    arrays = rows_to_arrays(rows, n_cells, gaps_from_rows(rows))
    attrs: dict[str, object] = {
        "source": source or "unknown",
        "capture": "rigtools logger, rebuilt from the CSV by --repair",
    }
    if not source:
        attrs["source_note"] = "the CSV does not say whether a rig or an emulator sent it (--source LABEL)"
    if topology is not None:
        attrs["topology"] = topology
    write_capture(prefix.with_suffix(".npz"), arrays, attrs)
    stale = prefix.with_name(prefix.name + ".npz.tmp")
    if stale.exists():
        stale.unlink()
    return arrays
