"""The import rules of docs/architecture.md, checked by reading the code (AST), not by importing it.

Every ``import``/``from … import`` anywhere in a module (inside functions too) counts.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: ofbe_data wing → the ofbe_data wings it may import (itself included).
DATA_RULES: dict[str, frozenset[str]] = {
    "core": frozenset({"core"}),
    "io": frozenset({"core", "io"}),
    "simulator": frozenset({"core", "io", "simulator"}),
    "labelling": frozenset({"core", "io", "labelling"}),
    "dataset": frozenset({"core", "io", "labelling", "dataset"}),
    "reports": frozenset({"core", "io", "labelling", "dataset", "reports"}),
    "calibration": frozenset({"core", "io", "labelling", "calibration"}),
    "freeliving": frozenset({"core", "io", "labelling", "freeliving"}),
    "cli": frozenset({"core", "io", "simulator", "labelling", "dataset", "reports", "calibration",
                      "freeliving", "cli"}),
}
#: Top-level modules of ofbe_data that are not in a wing, and what they may import.
DATA_TOP = {"__init__": frozenset({"dataset", "labelling", "calibration"})}
MAX_LINES = 600


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, imported module) of every absolute import in a file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
            # ``from ofbe_data import io`` names a subpackage
            found += [(node.lineno, f"{node.module}.{a.name}") for a in node.names
                      if node.module in ("ofbe_data", "ofbe_model")]
    return found


def violations(path: Path, rel: str) -> list[str]:
    """Every import of ``path`` (repository-relative ``rel``) that breaks a rule."""
    parts = rel.removesuffix(".py").split("/")
    package = parts[0]
    out = []
    for line, mod in _imports(path):
        top = mod.split(".")
        where = f"{rel}:{line}: imports {mod}"
        if top[0] == "pipelines" and package != "pipelines":
            out.append(f"{where} (nothing imports pipelines)")
        if package == "ofbe_data":
            if top[0] == "ofbe_model":
                out.append(f"{where} (ofbe_data never imports ofbe_model)")
            elif top[0] == "ofbe_data" and len(top) > 1 and top[1] in DATA_RULES:
                wing = parts[1] if len(parts) > 2 else None
                allowed = DATA_RULES[wing] if wing in DATA_RULES else DATA_TOP.get(parts[1], frozenset())
                if top[1] not in allowed:
                    out.append(f"{where} ({wing or parts[1]} may import {', '.join(sorted(allowed))} only)")
        elif package == "ofbe_model":
            if top[:2] == ["ofbe_data", "cli"]:
                out.append(f"{where} (command lines are imported by nothing)")
            if top[:2] == ["ofbe_model", "cli"] and parts[1] != "cli":
                out.append(f"{where} (command lines are imported by nothing)")
    return out


def _sources(*packages: str) -> list[Path]:
    return sorted(p for pkg in packages for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("package", ["ofbe_data", "ofbe_model", "benchmarks"])
def test_every_import_follows_the_rules(package: str) -> None:
    found = [v for p in _sources(package) for v in violations(p, p.relative_to(ROOT).as_posix())]
    assert found == []


@pytest.mark.parametrize("source, rel, expected", [
    ("from ofbe_model.estimators import make_estimator\n", "ofbe_data/dataset/build.py",
     "ofbe_data never imports ofbe_model"),
    ("def f():\n    from ofbe_data.simulator import simulate_campaign\n", "ofbe_data/labelling/labels.py",
     "labelling may import core, io, labelling only"),
    ("import pipelines.label\n", "ofbe_model/predict.py", "nothing imports pipelines"),
    ("from ofbe_data.labelling.orientation import roll_pitch\n", "ofbe_data/simulator/campaign.py",
     "simulator may import core, io, simulator only"),
    ("from ofbe_data.dataset.reader import load_dataset\n", "ofbe_data/io/manifest.py",
     "io may import core, io only"),
    ("from ofbe_data.cli.label import main\n", "ofbe_model/benchmark/runner.py",
     "command lines are imported by nothing"),
])
def test_a_forbidden_import_is_reported(tmp_path: Path, source: str, rel: str, expected: str) -> None:
    path = tmp_path / "m.py"
    path.write_text(source)
    found = violations(path, rel)
    assert len(found) == 1 and expected in found[0] and found[0].startswith(rel + ":")


def test_an_allowed_import_is_not_reported(tmp_path: Path) -> None:
    path = tmp_path / "m.py"
    path.write_text("from ofbe_data.io.manifest import load_manifest\n"
                    "from ofbe_data.core.errors import OfbeError\n")
    assert violations(path, "ofbe_data/labelling/labels.py") == []


@pytest.mark.parametrize("package", ["ofbe_data", "ofbe_model", "pipelines"])
def test_no_module_is_over_the_size_limit(package: str) -> None:
    sizes = {p.relative_to(ROOT).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
             for p in _sources(package)}
    assert {k: v for k, v in sizes.items() if v > MAX_LINES} == {}


def test_every_package_says_what_it_holds_and_may_import() -> None:
    for init in _sources("ofbe_data", "ofbe_model"):
        if init.name != "__init__.py":
            continue
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and "import" in doc, init.relative_to(ROOT)
