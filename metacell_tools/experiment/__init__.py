"""Experiment runner (docs/physics.md#experiments on the rig through the primary), its rehearsal against the emulator,
and the rig-vs-emulator comparison."""
