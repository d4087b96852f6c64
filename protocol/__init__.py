"""The rig's one wire definition: data (definition), Python view (wire), SI <-> register codec (codec), generator.

Regenerate the C headers, the DBC and the tables after editing definition.py: ``python -m protocol.generate``.
"""
