"""Entry point: python -m tools.experiment run|rehearse|compare (see docs/experiments.md)."""

from .cli import main

raise SystemExit(main())
