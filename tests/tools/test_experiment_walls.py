"""The experiment summary says where its walls are: the bonds j + 0.5 on the rig's cell numbers (a cell without
data left out, not renumbered), per repeat and the positions most repeats agree on."""

from __future__ import annotations

import numpy as np

from metacell_tools.experiment.summary import _most_common, _wall_bonds


def test_bonds_of_a_full_chain_are_the_sign_changes():
    alpha = np.array([0.5, 0.6, -0.5, -0.6, 0.4])
    assert _wall_bonds(alpha, np.ones(5, bool), {"at_rest": False}) == [2.5, 4.5]


def test_a_cell_without_data_keeps_the_others_numbers():
    # cell 3 sent nothing: the wall between cells 2 and 4 sits at bond 3.5 (renumbering the present cells would
    # put it at 2.5, between the rig's cells 2 and 3)
    alpha = np.array([0.5, 0.5, np.nan, -0.5, -0.5])
    present = np.array([True, True, False, True, True])
    assert _wall_bonds(alpha, present, {"at_rest": False}) == [3.5]


def test_at_rest_has_no_walls_and_no_data_has_no_answer():
    alpha = np.array([0.01, -0.01, 0.01])
    assert _wall_bonds(alpha, np.ones(3, bool), {"at_rest": True}) == []
    assert _wall_bonds(alpha, np.zeros(3, bool), {}) is None


def test_the_summary_takes_the_positions_most_repeats_agree_on():
    assert _most_common([[2.5, 8.5], [2.5], [2.5, 8.5]]) == [2.5, 8.5]
    assert _most_common([None, [4.5], None]) == [4.5]
    assert _most_common([None, None]) is None and _most_common([]) is None
