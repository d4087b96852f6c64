"""The sweep's two errors: a bad definition (exit 2) and a sweep that could not run on (exit 3)."""


class SweepError(ValueError):
    """A bad sweep definition (grid syntax, keys, output directory)."""


class SweepFailed(RuntimeError):
    """The sweep could not run on (scheduler unreachable, cluster failed to start, interrupted); points already
    finished stay in points.jsonl and a re-run resumes."""
