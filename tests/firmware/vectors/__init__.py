"""Bus test vectors shared by pytest (through cffi) and the Unity suites under test/ (through generated C headers).

Each module lists inputs and derives the expected outputs from an independent Python reference model of the
documented behaviour (never from the C library): `regs` (cell register handler), `slcan` (SLCAN codec) and
`primary` (poll scheduler and command path). `python -m tests.firmware.vectors OUT_DIR` writes the headers;
PlatformIO's native environment runs that at build time (tests/firmware/vectors/pio_vectors.py), so no header
is kept in git.
"""
