"""The image's row of docs/accuracy.md#tiers: the hil's max angle difference from the flashed images on the default
scene over 3 s is the figure the tier table prints and `run` quotes (tests/docs/test_tiers_table.py checks the
others; this one costs seconds of CPU, the image running at about 0.3x real time)."""

import pytest

from host_emulator.benchmarks import tiers as tb
from host_emulator.tiers import ERROR_VS_UP_RAD


@pytest.mark.slow
def test_the_hil_to_image_difference_is_the_tables(images):
    assert f"{tb.tier_error('hil'):.2g}" == f"{ERROR_VS_UP_RAD['hil']:.2g}"
