"""Output-path checks: metacell_common.outpaths (shared with the laptop tools), under their old name."""

from metacell_common.outpaths import SHOW, check_out_dir, check_out_file, first_problem, show

__all__ = ["SHOW", "check_out_dir", "check_out_file", "first_problem", "show"]
