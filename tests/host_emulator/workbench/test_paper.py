"""`paper`: every item of the source's Fig. 2 and 3 is computed, compared and written; the figures exist."""

import json

from host_emulator.cli import main
from host_emulator.workbench.paper import build


def test_paper_items_agree_with_the_source(tmp_path):
    doc = build(tmp_path, repeats=2)
    figs = {i["figure"] for i in doc["items"]}
    assert {"2a.i", "2b.i", "2c.i", "2a.ii", "2b.ii", "2c.ii", "exp. 4", "3a", "3b", "3c"} <= figs
    bad = [i for i in doc["items"] if not i["agree"]]
    assert not bad, bad
    assert doc["agree"] == doc["total"] == 14
    on_disk = json.loads((tmp_path / "paper.json").read_text())
    assert on_disk["total"] == len(doc["items"]) and on_disk["agree"] == doc["agree"]
    for f in doc["files"]:
        assert (tmp_path / f).stat().st_size > 10_000


def test_paper_rejects_bad_arguments(tmp_path, capsys):
    assert main(["paper", "--repeats", "0", "--out", str(tmp_path)]) == 2
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["paper", "--out", str(f)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_robustness_counts_seeds_and_pushes_that_select_the_source():
    from host_emulator.workbench.robustness import robustness, selects

    res = robustness(seeds=2, torques=(0.01, 0.02), durations=(0.1,), scenes=["exp2_ccw_cw", "exp5_rest"])
    assert res["exp2_ccw_cw"]["seeds"] == 1.0 and res["exp2_ccw_cw"]["pushes"] == 1.0
    assert res["exp2_ccw_cw"]["min_push_Nm"] == 0.01 and len(res["exp2_ccw_cw"]["push_grid"]) == 2
    assert res["exp5_rest"]["seeds"] == 1.0 and res["exp5_rest"]["pushes"] is None
    # under the rig's uncertainty too (band, viscosity, inertia, push and timing drawn): exp2's three walls hold
    assert res["exp2_ccw_cw"]["seeds_rig"] == 1.0 and 0 <= res["exp5_rest"]["seeds_rig"] <= 1
    # a jittering encoder reading is itself a push: rest does not survive it at 9/125
    assert res["exp5_rest"]["seeds_jitter"] < 1.0
    assert selects({"at_rest": False, "domain_walls": 3}, 3) and not selects({"at_rest": True, "domain_walls": 0}, 3)
    assert selects({"oscillation_period_s": 0.0291}, 0.03) and not selects({"oscillation_period_s": 0.055}, 0.03)
