"""Every command's ``--help``: an example, help text for every option, defaults shown one way,
``ofbe-export FORMAT --help`` with that format's options only, and ``--help`` (or a usage error)
answered without the heavy libraries (docs/architecture.md, "Command lines")."""

from __future__ import annotations

import argparse
import importlib
import json
import re
import subprocess
import sys
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


HEAVY = ("pandas", "pyarrow", "scipy", "h5py", "tensorflow", "keras", "matplotlib", "dask", "distributed")
"""Libraries no command may import to answer ``--help`` or a usage error (each takes a second or
more to import; NumPy and PyYAML, a tenth, may be)."""
HELP_PROBE = """\
import json, sys
from {module} import {func}
codes = []
for argv in {argvs!r}:
    sys.argv = [{script!r}, *argv]
    try:
        codes.append({func}())
    except SystemExit as exc:
        codes.append(exc.code)
print("PROBE " + json.dumps({{"codes": codes, "modules": sorted(sys.modules)}}))
"""
"""Runs a console script's function (pyproject.toml's target, as pip's script does) on each
command line in turn, then prints the exit codes and every module the process imported."""


def _argvs(script: str) -> list[list[str]]:
    """A usage error, ``--help``, and ``--help`` of each subcommand (every ``ofbe-export`` format)."""
    subs: tuple[str, ...] = SUBCOMMANDS.get(script, ())
    if script == "ofbe-export":
        from ofbe_data.calibration.exports import export_names

        subs = export_names()
    return [["--no-such-option"], ["--help"], *([sub, "--help"] for sub in subs)]


@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_help_and_usage_errors_import_no_heavy_library(script: str) -> None:
    module, func = SCRIPTS[script].split(":")
    argvs = _argvs(script)
    code = HELP_PROBE.format(module=module, func=func, argvs=argvs, script=script)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                          timeout=300, check=False)  # a hang guard: a healthy run takes a second
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("PROBE ")), None)
    assert line is not None, f"{script}: no probe line; stderr: {done.stderr[-2000:]}"
    probe = json.loads(line.removeprefix("PROBE "))
    expected = [2] + [0] * (len(argvs) - 1)  # argparse's usage error, then each help
    assert probe["codes"] == expected, (script, argvs, probe["codes"], done.stderr[-2000:])
    assert f"{script}: error: unrecognized arguments: --no-such-option" in done.stderr \
        or f"{script}: error: the following arguments are required" in done.stderr, done.stderr[-2000:]
    heavy = sorted({m for m in probe["modules"] if m.split(".")[0] in HEAVY})
    assert heavy == [], f"{script} --help imports {sorted({m.split('.')[0] for m in heavy})}"


def test_simulate_help_lists_the_simulators_own_profiles() -> None:
    from ofbe_data.cli.simulate import profile_names
    from ofbe_data.simulator import builtin_profiles

    assert profile_names() == builtin_profiles() and "tiny-rotated" in profile_names()
