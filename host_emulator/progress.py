"""Progress bars: metacell_common.progress (shared with the host build of the firmware), under their old name."""

from metacell_common.progress import bar

__all__ = ["bar"]
