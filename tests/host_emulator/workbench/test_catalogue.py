"""The run catalogue: he.runs(DIR) and `python -m host_emulator runs DIR` list every run and capture under a folder,
one row each, with what each already carries (scene, model, parameters, pattern, walls, source, git, date)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import host_emulator as he
from host_emulator.cli import main
from host_emulator.workbench.catalogue import COLUMNS
from host_emulator.workbench.datasets import from_logger_arrays, to_npz
from protocol.capture import CSV_HEADER, RAD_PER_COUNT, format_rows, rows_to_arrays

ROOT = Path(__file__).resolve().parents[3]


def _capture_rows(alpha, beta):
    ca, cb = np.round(alpha / RAD_PER_COUNT).astype(int), np.round(beta / RAD_PER_COUNT).astype(int)
    return [
        (0, k, j, 0.01 * k, 1000.0 + 0.01 * k, ca[k, j - 1], cb[k, j - 1], 0)
        for k in range(len(alpha))
        for j in range(1, alpha.shape[1] + 1)
    ]


def _folder(tmp: Path) -> dict:
    """Two runs (one nested), a logger capture (NPZ with its CSV), a lone logger CSV, an unreadable NPZ, and what is
    no run: a hidden folder, a table CSV."""
    runs = {}
    for rel, sets in (("a/sig5", ["params.sigma=0.05"]), ("b/deep/default", [])):
        out = tmp / rel
        argv = ["run", "default", "--set", "t_end_s=3", *sum((["--set", s] for s in sets), []), "--out", str(out)]
        assert main([*argv, "--quiet", "--no-plots"]) == 0
        runs[rel] = json.loads((out / "summary.json").read_text())
    r = he.run("exp2_ccw_cw", overrides={"t_end_s": 3})
    rows = _capture_rows(r.alpha, r.beta)
    (tmp / "caps").mkdir()
    to_npz(from_logger_arrays(rows_to_arrays(np.array(rows, float), 16, []), {"source": "rig"}), tmp / "caps/rig1.npz")
    (tmp / "caps/rig1.csv").write_text(CSV_HEADER + format_rows(rows))
    (tmp / "caps/lone.csv").write_text(CSV_HEADER + format_rows(rows))
    (tmp / "caps/broken.npz").write_bytes(b"PK\x03\x04 cut")
    (tmp / ".hidden").mkdir()
    (tmp / ".hidden/x.npz").write_bytes(b"")
    (tmp / "table.csv").write_text("sigma,walls\n0.05,2\n")
    return {"runs": runs, "capture": r}


def test_runs_lists_every_run_and_capture_with_what_it_carries(tmp_path):
    made = _folder(tmp_path)
    df = he.runs(tmp_path)
    assert isinstance(df, pd.DataFrame) and tuple(df.columns) == COLUMNS
    assert list(df["path"]) == ["a/sig5", "b/deep/default", "caps/broken.npz", "caps/lone.csv", "caps/rig1.npz"]
    rows = df.set_index("path")
    for rel, s in made["runs"].items():
        row = rows.loc[rel]
        assert (row["kind"], row["scene"], row["model"], row["source"]) == ("run", "default", "hil", "emulator:hil")
        assert row["walls"] == s["domain_walls"] and row["wall_bonds"] == s["domain_wall_bonds"]
        assert row["pattern"] == s["pattern_wavelength_cells"]
        assert row["git"] == s["provenance"]["git_describe"] and row["date"] == s["provenance"]["created_utc"]
    assert rows.loc["a/sig5", "parameters"] == "sigma=0.05"
    assert rows.loc["b/deep/default", "parameters"] == ""  # the defaults: nothing to say
    # the captures: their walls from their final profile, the same as the emulator's run they were made from
    ref = made["capture"].summary
    for rel in ("caps/rig1.npz", "caps/lone.csv"):
        row = rows.loc[rel]
        assert row["kind"] == "capture" and row["walls"] == ref["domain_walls"] == 3
        assert row["wall_bonds"] == ref["domain_wall_bonds"]
    assert rows.loc["caps/rig1.npz", "source"] == "rig"
    assert rows.loc["caps/lone.csv", "source"] == "unknown"
    assert "caps/broken.npz" in rows.index and "not a readable NPZ" in rows.loc["caps/broken.npz", "note"]


def test_runs_of_an_empty_folder_is_an_empty_table(tmp_path):
    df = he.runs(tmp_path)
    assert df.empty and tuple(df.columns) == COLUMNS


def test_runs_command_prints_the_table_and_writes_csv(tmp_path, capsys):
    _folder(tmp_path)
    csv = tmp_path / "out" / "runs.csv"
    assert main(["runs", str(tmp_path), "--csv", str(csv)]) == 0
    text = capsys.readouterr().out
    for rel in ("a/sig5", "b/deep/default", "caps/rig1.npz", "sigma=0.05", "emulator:hil"):
        assert rel in text
    back = pd.read_csv(csv)
    assert list(back.columns) == list(COLUMNS) and list(back["path"]) == list(he.runs(tmp_path)["path"])


def test_runs_command_rejects_what_is_no_folder_in_one_line(tmp_path):
    f = tmp_path / "file.txt"
    f.write_text("x")
    for argv in ([str(tmp_path / "missing")], [str(f)], [str(tmp_path), "--csv", str(tmp_path / "x.txt")]):
        r = subprocess.run(
            [sys.executable, "-m", "host_emulator", "runs", *argv],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert r.returncode == 2, (argv, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]
