"""`experiment rehearse` runs the hil emulator's serve: asked for model = image it refuses in one line (exit 2) rather
than rehearsing another tier than the one named (issue 32, item 6)."""

from metacell_tools.experiment import cli


def test_rehearse_refuses_the_image_tier(tmp_path, capsys):
    out = tmp_path / "o"
    assert cli.main(["rehearse", "default", "--set", "model=image", "--out", str(out)]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "model = image" in err and "serve" in err and err.count("\n") == 1, err
    assert not out.exists()
