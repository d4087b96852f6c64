"""The rig's one wire definition: data (definition), Python view (wire), SI <-> register codec (codec), generator,
and the capture decoder beside it (capture: CELL_SAMPLE frames to rows and cycle x cell arrays).

Regenerate the C headers, the DBC and the tables after editing definition.py: ``python -m protocol.generate``.
"""
