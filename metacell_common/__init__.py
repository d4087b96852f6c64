"""What the emulator and the laptop tools share, below both."""
