"""Benchmarks of the emulator: work-precision against scipy/py-pde, fidelity cost, scaling (`python -m host_emulator
bench`)."""
