"""Experiment runner (SPEC 1.5 on the rig through the primary), its rehearsal against the emulator, and the rig-vs-emulator comparison."""
