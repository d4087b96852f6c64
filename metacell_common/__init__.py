"""What the emulator and the laptop tools share, below both: the run layout and its NPZ writer (runlayout), provenance,
output-path checks (outpaths), the serial-port lock (portlock), one-line CLI errors (cli), progress bars, the reaction
law's firmware defaults (reaction), the host build of the firmware library (firmware) and the SAMD21/XIAO target
facts (target/). It imports protocol/ and third-party packages only (pyproject.toml [tool.importlinter] holds it)."""
