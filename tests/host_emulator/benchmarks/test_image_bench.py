"""The image-tier benchmark's command line: out-of-range arguments refused (one line, exit 2), no world built."""

import pytest

from host_emulator.benchmarks import image as ib


@pytest.mark.parametrize("argv", [["--seconds", "0"], ["--reps", "0"], ["--threads", "17"]])
def test_bad_arguments_exit_2(argv, capsys):
    assert ib.main(argv) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.count("\n") == 1 and out.err.startswith("benchmark:")


@pytest.mark.parametrize("argv", [["--seconds", "0"], ["--seconds", "3"], ["--top", "51"]])
def test_instruction_benchmark_bad_arguments_exit_2(argv, capsys):
    from host_emulator.benchmarks import image_instructions as ii

    assert ii.main(argv) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.count("\n") == 1 and out.err.startswith("benchmark:")
