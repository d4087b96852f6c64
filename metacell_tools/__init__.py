"""Laptop-side tools: flashing, logging, commands, firmware checks."""
