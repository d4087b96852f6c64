"""Firmware proof offline: ARM cross-build checks, QEMU golden vectors and instruction counts."""
