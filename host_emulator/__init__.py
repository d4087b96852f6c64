"""Host emulator of the pattern-forming robotic metamaterial: the shipped firmware against a simulated plant."""
