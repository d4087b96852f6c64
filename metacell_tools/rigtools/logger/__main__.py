"""`python -m metacell_tools.rigtools.logger`: the rig logger's command line (cli.main)."""

from .cli import main

raise SystemExit(main())
