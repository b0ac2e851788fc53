"""The install the README and CI promise: pyproject's ranges, the constraints file of tested
versions, and the README's two commands, kept consistent with each other.

A fresh machine installs ``pip install -c constraints.txt -e ".[dev]"``; if constraints.txt
pinned a version outside pyproject's range, or forgot a dependency, pip would fail or install
an untested version. This reads the files themselves, so it fails as soon as one of them is
edited without the other.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
README_TEST = 'python -m pip install -c constraints.txt -e ".[dev]" && python -m pytest'
README_MAIN = "python -m pip install -c constraints.txt -e . && dvc repro"
MAKE_VENV = "python -m venv .venv && . .venv/bin/activate"


def _pins() -> dict[str, Version]:
    pins: dict[str, Version] = {}
    for number, line in enumerate((ROOT / "constraints.txt").read_text().splitlines(), start=1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        match = re.fullmatch(r"([A-Za-z0-9][A-Za-z0-9._-]*)==([0-9][A-Za-z0-9.+!-]*)", line)
        assert match, f"constraints.txt:{number}: expected 'name==version', found {line!r}"
        name = canonicalize_name(match.group(1))
        assert name not in pins, f"constraints.txt:{number}: {name} pinned twice"
        pins[name] = Version(match.group(2))
    return pins


def _requirements() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project.get("optional-dependencies", {})
    return [Requirement(r) for r in [*project["dependencies"], *extras.get("dev", [])]]


@pytest.mark.parametrize("requirement", _requirements(), ids=lambda r: r.name)
def test_every_dependency_is_pinned_inside_its_range(requirement: Requirement) -> None:
    pins = _pins()
    name = canonicalize_name(requirement.name)
    assert name in pins, f"constraints.txt has no pin for {requirement.name} (pyproject asks {requirement})"
    assert requirement.specifier.contains(pins[name], prereleases=True), (
        f"constraints.txt pins {requirement.name}=={pins[name]}, outside pyproject's {requirement}")


def test_ofbe_itself_is_not_pinned() -> None:
    assert "ofbe" not in _pins(), "constraints.txt must not pin the project itself (pip freeze's -e line)"


def test_readme_and_ci_install_the_same_way() -> None:
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    for command in (README_TEST, README_MAIN, MAKE_VENV):
        assert command in readme, f"README.md lacks the command {command!r}"
    code = [line.strip() for line in ci.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert any(line.startswith("python -m venv .venv ||") for line in code), ".ci/run makes no fresh venv"
    assert ". .venv/bin/activate" in code
    install, test = README_TEST.split(" && ")
    assert any(line.startswith(install + " ||") for line in code), f".ci/run does not run {install!r}"
    assert test in code, f".ci/run does not run {test!r}"
