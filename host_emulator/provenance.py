"""Provenance of an output: metacell_common.provenance (shared with the laptop tools), under its old name."""

from metacell_common.provenance import (
    cpu_model,
    firmware_build,
    git_describe,
    machine,
    machine_line,
    provenance,
)

__all__ = ["cpu_model", "firmware_build", "git_describe", "machine", "machine_line", "provenance"]
