"""Benchmarks of the emulator (issue 5): work-precision against scipy/py-pde, fidelity cost, scaling (`python -m host_emulator bench`)."""
