"""The rig's 16 boards as a 4 x 4 sheet in the image tier (issue 30): the flashed cell images and the primary on the
plant whose bonds come from the scene's lattice; a push reaches the pushed cell's four bonded neighbours first, the
run follows the hil run of the same scene, and two threads give the same result as one."""

from __future__ import annotations

import numpy as np
import pytest

from host_emulator.controller import build_solver, run_solver
from host_emulator.models.options import ConfigError
from host_emulator.scene import load_scene
from host_emulator.tiers import ERROR_VS_UP_RAD

pytestmark = pytest.mark.slow

T_END = ["t_end_s=0.3"]  # the push is at 0.1..0.2 s: 0.3 s costs ~6 s of CPU per image run


def run(overrides: list[str]):
    sc = load_scene("sheet_4x4_rig", [*T_END, *overrides])
    return run_solver(build_solver(sc), sc.t_end_s)


@pytest.fixture(scope="module")
def image_run(images):
    return run(["model=image"])


def test_a_push_at_2_2_reaches_its_four_bonded_neighbours_first(image_run):
    """20 ms into the push on cell 6 (row 2, col 2), each of its bonded neighbours 2, 5, 7, 10 has turned more than
    every cell not bonded to it. A chain of 16 would bond 6 to 5 and 7 only, with 2 and 10 four bonds away and 4
    and 8 two: there cell 3 (three bonds) would move before cell 10 (four); on the sheet 10 is one bond, 3 two."""
    r = image_run
    k = int(np.argmin(np.abs(r.t - 0.12)))
    assert abs(r.t[k] - 0.12) < 1e-9
    assert np.abs(r.alpha[r.t < 0.1]).max() == 0.0  # at rest until the push
    moved = np.abs(r.alpha[k])  # index j - 1 is cell j
    bonded = [2, 5, 7, 10]
    others = [j for j in range(1, 17) if j not in (6, *bonded)]
    assert moved[5] > max(moved[j - 1] for j in bonded)  # the pushed cell most
    assert min(moved[j - 1] for j in bonded) > max(moved[j - 1] for j in others)
    assert moved[10 - 1] > 1.5 * moved[3 - 1]  # the comparison a chain gets the other way round
    assert moved[2 - 1] > 3 * moved[4 - 1]  # on a chain cell 4 is two bonds from 6, cell 2 four
    # a push on the diagonal: the sheet's transpose (row, col) -> (col, row) maps the run onto itself
    grid = r.alpha.reshape(len(r.t), 4, 4)
    assert np.abs(grid - grid.transpose(0, 2, 1)).max() < 0.01


def test_the_image_sheet_follows_the_hil_sheet(image_run):
    """At the same output times the flashed images' sheet stays within the hil-to-image difference the tier table
    quotes (ERROR_VS_UP_RAD['hil'], the default scene over 3 s), and both grow the same pattern."""
    hil = run(["model=hil"])
    assert hil.t.shape == image_run.t.shape and np.allclose(hil.t, image_run.t, rtol=0, atol=1e-9)
    assert np.abs(hil.alpha - image_run.alpha).max() < ERROR_VS_UP_RAD["hil"]
    strong = np.abs(hil.alpha[-1]) > 0.1  # the cells the pattern has turned: the same signs
    assert strong.sum() >= 8 and (hil.alpha[-1][strong] * image_run.alpha[-1][strong] > 0).all()


def test_two_threads_give_the_same_sheet(image_run):
    two = run(["model=image", "model_options.image.threads=2"])
    assert np.array_equal(two.alpha, image_run.alpha) and np.array_equal(two.beta, image_run.beta)


def test_a_sheet_beyond_the_rigs_16_boards_is_refused_in_one_line():
    with pytest.raises(ConfigError, match=r"^model = 'image' with cells = \[8, 8\]: .* 16 cell boards .*not 64"):
        load_scene("sheet_8x8", ["model=image"])
