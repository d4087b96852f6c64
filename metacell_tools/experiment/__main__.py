"""Entry point: python -m metacell_tools.experiment run|rehearse|compare (see docs/experiments.md)."""

from .cli import main

raise SystemExit(main())
