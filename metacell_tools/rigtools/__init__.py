"""Laptop tools for the rig's data path on python-can: protocol helpers, logger, command tool (see docs/datapath.md)."""
