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
