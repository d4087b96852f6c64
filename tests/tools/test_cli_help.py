"""Every command-line parser (top level and every subcommand) documents every argument and shows examples."""

import argparse
import importlib

import pytest

from host_emulator.cli import SUBCOMMANDS


class _Parsed(BaseException):
    """Raised instead of parsing: carries the parser the entry point built (a BaseException, so it passes the entry
    points' last guard, which turns any Exception into one line and exit 3)."""


def entry_points() -> list[tuple[str, str]]:
    """(module, function) of every CLI; the emulator's subcommands straight from its own table."""
    eps = [("host_emulator.cli", "main")]
    eps += [("host_emulator" + m if m.startswith(".") else m, f) for m, f in SUBCOMMANDS.values()]
    eps += [
        ("metacell_tools.rigtools.logger", "main"),
        ("metacell_tools.rigtools.command", "main"),
        ("metacell_tools.experiment.cli", "main"),
        ("metacell_tools.flash.__main__", "main"),
        ("metacell_tools.fwcheck.__main__", "main"),
        ("host_emulator.benchmarks.sweep", "main"),
        ("host_emulator.benchmarks.bus", "main"),
        ("host_emulator.benchmarks.instructions", "main"),
    ]
    return list(dict.fromkeys(eps))


def built_parser(module: str, func: str, monkeypatch) -> argparse.ArgumentParser:
    """The parser `module.func([])` builds (caught when it starts parsing: nothing runs)."""

    def grab(self, args=None, namespace=None):
        raise _Parsed(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", grab)
    with pytest.raises(_Parsed) as got:
        getattr(importlib.import_module(module), func)([])
    return got.value.args[0]


def problems(parser: argparse.ArgumentParser, path: str) -> list[str]:
    """Arguments without help, subcommands without help, parsers without examples in their epilog."""
    out = []
    if not parser.epilog or "example" not in parser.epilog.lower():
        out.append(f"{path}: no examples in the epilog")
    for a in parser._actions:
        if isinstance(a, argparse._HelpAction):
            continue
        if isinstance(a, argparse._SubParsersAction):
            helps = {c.dest: c.help for c in a._choices_actions}
            if not a.help:
                out.append(f"{path}: the subcommand argument has no help")
            for name, sub in a.choices.items():
                if not helps.get(name):
                    out.append(f"{path} {name}: subcommand without help")
                out += problems(sub, f"{path} {name}")
            continue
        if not a.help or a.help == argparse.SUPPRESS or not a.help.strip():
            out.append(f"{path}: argument {'/'.join(a.option_strings) or a.dest} has no help")
    return out


@pytest.mark.parametrize("module,func", entry_points())
def test_every_argument_has_help_and_every_parser_examples(module, func, monkeypatch):
    p = built_parser(module, func, monkeypatch)
    assert problems(p, p.prog) == []


def test_the_walker_finds_what_is_missing():
    """The check itself can fail: an argument without help and a subparser without examples are both named."""
    ap = argparse.ArgumentParser(prog="x", epilog="example: x a")
    ap.add_argument("--good", help="fine")
    ap.add_argument("--bad")
    sub = ap.add_subparsers(dest="cmd", help="what")
    s = sub.add_parser("a", help="a thing")
    s.add_argument("pos")
    sub.add_parser("b")
    got = problems(ap, "x")
    assert "x: argument --bad has no help" in got and "x a: argument pos has no help" in got
    assert "x a: no examples in the epilog" in got and "x b: subcommand without help" in got
    assert not any("--good" in g for g in got)


def test_help_prints_for_every_subcommand(capsys):
    """--help of each emulator subcommand and tool exits 0 and shows its examples."""
    from host_emulator import cli

    for name in ["run", "scenes", *SUBCOMMANDS]:
        with pytest.raises(SystemExit) as e:
            cli.main([name, "--help"])
        assert e.value.code == 0
        assert "example" in capsys.readouterr().out, name
