"""The one definition of a board's build: the PlatformIO environment, its own build directory and the source-only flags
that give a cell its number and I2C address. The flash tool uploads exactly these builds (metacell_tools.flash.plan)
and the emulator's image tier runs them (host_emulator.image.build)."""

from __future__ import annotations

from pathlib import Path

from protocol.wire import MAX_CELLS, N_CELLS, cell_address

ROOT = Path(__file__).resolve().parents[2]  # the repository: platformio.ini, src/, lib/


def board_build_env(
    role: str, cell: int | None, project: Path = ROOT, build_root: Path | None = None, cells: int = N_CELLS
) -> tuple[str, tuple[tuple[str, str], ...]]:
    """(PlatformIO environment, environment variables) of one board's build: the one definition of what is flashed
    (the upload here, the emulator's image tier runs the same builds). A cell's number and address are src-only
    build flags (the library objects are the same for every cell), each board in its own build directory so
    rebuilds stay incremental (see docs/hardware.md). `cells`: how many cells the rig has (a sheet: up to
    MAX_CELLS); the primary of a rig other than the 16 cells as built polls them (-DMC_RIG_CELLS, its own build
    directory), the rig as built's primary is built exactly as before."""
    if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= MAX_CELLS:
        raise ValueError(f"cells {cells!r}: expected 1..{MAX_CELLS}")
    base = Path(build_root) if build_root is not None else Path(project) / ".pio"
    if role == "cell":
        if cell is None or not 1 <= cell <= cells:
            raise ValueError(f"cell {cell!r}: expected 1..{cells}")
        return "cell", (
            ("PLATFORMIO_BUILD_DIR", str(base / f"build-cell{cell:02d}")),
            ("PLATFORMIO_BUILD_SRC_FLAGS", f"-DMC_CELL_INDEX={cell} -DMC_CELL_ADDR=0x{cell_address(cell):02x}"),
        )
    if role == "primary" and cells != N_CELLS:
        return "primary", (
            ("PLATFORMIO_BUILD_DIR", str(base / f"build-primary-{cells}cells")),
            ("PLATFORMIO_BUILD_SRC_FLAGS", f"-DMC_RIG_CELLS={cells}"),
        )
    if role == "primary":
        return "primary", (
            ("PLATFORMIO_BUILD_DIR", str(base / "build-primary")),
            ("PLATFORMIO_BUILD_SRC_FLAGS", ""),  # cancel any inherited cell flags
        )
    raise ValueError(f"role {role!r}: expected 'cell' or 'primary'")
