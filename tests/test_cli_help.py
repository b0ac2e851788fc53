"""Every command's ``--help``: an example, help text for every option, defaults shown one way,
and ``ofbe-export FORMAT --help`` with that format's options only."""

from __future__ import annotations

import argparse
import importlib
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
SUBCOMMANDS = {"ofbe-session": ("init", "check"), "ofbe-dataset": ("build", "verify", "export")}


def _module(script: str):
    entry = importlib.import_module(SCRIPTS[script].split(":")[0])
    return importlib.import_module(getattr(entry, SCRIPTS[script].split(":")[1]).command_module)


def _help(script: str, *args: str, capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        _module(script).main([*args, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


def _cases() -> list[tuple[str, tuple[str, ...]]]:
    out: list[tuple[str, tuple[str, ...]]] = []
    for script in SCRIPTS:
        out.append((script, ()))
        out += [(script, (sub,)) for sub in SUBCOMMANDS.get(script, ())]
    return out


@pytest.mark.parametrize(("script", "args"), _cases(),
                         ids=lambda v: " ".join(v) if isinstance(v, tuple) else v)
def test_help_shows_an_example_of_the_command_itself(script: str, args: tuple[str, ...],
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(script, *args, capsys=capsys)
    block = text.split("examples:\n", 1)
    assert len(block) == 2, f"{script} {' '.join(args)} --help shows no examples"
    first = block[1].splitlines()[0].strip()
    assert first.startswith(" ".join((script, *args))), first


def _parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    out = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out += _parsers(sub)
    return out


def _parser_of(script: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
               ) -> argparse.ArgumentParser:
    """The command's parser, caught as ``main`` parses ``--help``."""
    seen: list[argparse.ArgumentParser] = []
    real = argparse.ArgumentParser.parse_args

    def spy(self, *a, **k):
        seen.append(self)
        return real(self, *a, **k)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", spy)
    with pytest.raises(SystemExit):
        _module(script).main(["--help"])
    capsys.readouterr()
    return seen[0]


@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_every_option_has_help_and_its_default_is_shown_one_way(script: str, capsys, monkeypatch) -> None:
    for parser in _parsers(_parser_of(script, capsys, monkeypatch)):
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            name = "/".join(action.option_strings) or action.dest
            assert action.help, f"{parser.prog} {name}: no help text"
            text = parser.formatter_class(parser.prog)._get_help_string(action) % {
                **vars(action), "default": action.default, "prog": parser.prog}
            assert not re.search(r"\(default \S|\[default", text), f"{parser.prog} {name}: {text!r}"
            if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
                assert "default" in text, f"{parser.prog} {name}: default {action.default!r} not shown"


def test_export_format_help_shows_that_formats_options_only(capsys: pytest.CaptureFixture[str]) -> None:
    ros = _help("ofbe-export", "ros", capsys=capsys)
    tflite = _help("ofbe-export", "tflite", capsys=capsys)
    assert "--frame-id" in ros and "--dataset" not in ros and "--rostopic" not in ros
    assert "--dataset" in tflite and "--frame-id" not in tflite and "--raw" not in tflite
    assert "ofbe-export ros " in ros.split("examples:")[1]
