"""The image-tier benchmarks' command lines: out-of-range arguments refused (one line, exit 2), no world built."""

import pytest

from host_emulator.benchmarks import image as ib
from host_emulator.benchmarks import image_instructions as ii


@pytest.mark.parametrize(
    "main,argv",
    [
        (ib.main, ["--seconds", "0"]),
        (ib.main, ["--reps", "0"]),
        (ib.main, ["--threads", "17"]),
        (ii.main, ["--seconds", "0"]),
        (ii.main, ["--seconds", "3"]),
        (ii.main, ["--top", "51"]),
    ],
)
def test_bad_arguments_exit_2(main, argv, capsys):
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.count("\n") == 1 and out.err.startswith("benchmark:")


def test_a_kept_output_is_never_overwritten(tmp_path, capsys):
    """--keep PREFIX refuses, before anything runs, when PREFIX.CASE already holds a recorded output."""
    kept = tmp_path / "cg.full-speed"
    kept.write_text("recorded")
    assert ii.main(["--case", "default", "full-speed", "--keep", str(tmp_path / "cg")]) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1 and "not overwritten" in out.err
    assert kept.read_text() == "recorded" and not (tmp_path / "cg.default").exists()
