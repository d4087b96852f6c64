"""Entry point: python -m host_emulator (see cli.py)."""

import sys

from .cli import main

sys.exit(main())
