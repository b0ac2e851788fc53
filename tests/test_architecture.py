"""The import rules of docs/architecture.md, checked by reading the code (AST), not by importing it.

Every ``import``/``from … import`` anywhere in a module (inside functions too) counts.
"""

from __future__ import annotations

import ast
import functools
import warnings
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
    "calibration": frozenset({"core", "io", "labelling", "freeliving", "calibration"}),
    "freeliving": frozenset({"core", "io", "labelling", "freeliving"}),
    "cli": frozenset({"core", "io", "simulator", "labelling", "dataset", "reports", "calibration",
                      "freeliving", "cli"}),
}
#: Top-level modules of ofbe_data that are not in a wing, and what they may import.
DATA_TOP = {"__init__": frozenset({"core", "dataset", "labelling", "calibration"})}
#: ofbe_model wing → the ofbe_model wings it may import (itself included): estimators, then
#: the network, the benchmark, the deployed models, predictions, the command lines.
MODEL_RULES: dict[str, frozenset[str]] = {
    "estimators": frozenset({"estimators"}),
    "ofbenet": frozenset({"estimators", "ofbenet"}),
    "benchmark": frozenset({"estimators", "ofbenet", "benchmark"}),
    "deploy": frozenset({"estimators", "ofbenet", "benchmark", "deploy"}),
    "predict": frozenset({"estimators", "ofbenet", "deploy", "predict"}),
    "cli": frozenset({"estimators", "ofbenet", "benchmark", "deploy", "predict", "cli"}),
    "__init__": frozenset(),
}
SIZE_GUIDE = 600
"""Lines above which a module is worth a second look (a warning, not a failure: modules are cut
along concepts, not to fit a number)."""


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
            wing = parts[1]
            if top[0] == "ofbe_model" and len(top) > 1 and top[1] in MODEL_RULES and wing in MODEL_RULES:
                allowed = MODEL_RULES[wing]
                if top[1] not in allowed:
                    out.append(f"{where} ({wing} may import {', '.join(sorted(allowed)) or 'no wing'} only)")
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
    ("from ofbe_model.benchmark.runner import run_benchmark\n", "ofbe_model/ofbenet/training.py",
     "ofbenet may import estimators, ofbenet only"),
    ("from ofbe_model.predict import load_model\n", "ofbe_model/deploy/final.py",
     "deploy may import benchmark, deploy, estimators, ofbenet only"),
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


def test_modules_over_the_size_guide_are_named() -> None:
    """A guide, not a rule: a long module is named in a warning."""
    sizes = {p.relative_to(ROOT).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
             for p in _sources("ofbe_data", "ofbe_model", "pipelines")}
    long = {k: v for k, v in sizes.items() if v > SIZE_GUIDE}
    if long:
        warnings.warn(f"modules over {SIZE_GUIDE} lines (worth a second look): {long}", stacklevel=1)
    assert sizes  # the walk found the sources


def _module_name(path: Path) -> str:
    name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
    return name.removesuffix(".__init__")


def _runtime_imports(path: Path) -> list[tuple[int, str, str]]:
    """(line, module, name) of every ``from X import name`` of ours outside ``if TYPE_CHECKING:``
    blocks (anywhere else, functions included); ``name`` is "" for ``import X``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for child in node.body for n in ast.walk(child)}
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] in ("ofbe_data", "ofbe_model"):
            out += [(node.lineno, node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name, "") for a in node.names
                    if a.name.split(".")[0] in ("ofbe_data", "ofbe_model")]
    return out


def _graph() -> dict[str, set[str]]:
    """Module → the modules of ours it imports (``from pkg import submodule`` counts as the
    submodule, not the package)."""
    files = {_module_name(p): p for p in _sources("ofbe_data", "ofbe_model")}
    graph: dict[str, set[str]] = {m: set() for m in files}
    for mod, path in files.items():
        for _, target, name in _runtime_imports(path):
            graph[mod].add(f"{target}.{name}" if f"{target}.{name}" in files else target)
    return {m: {t for t in ts if t in files and t != m} for m, ts in graph.items()}


def test_no_module_imports_another_modules_private_name() -> None:
    files = {_module_name(p) for p in _sources("ofbe_data", "ofbe_model")}
    found = [f"{p.relative_to(ROOT)}:{line}: {name} from {target}"
             for p in _sources("ofbe_data", "ofbe_model", "pipelines")
             for line, target, name in _runtime_imports(p)
             if target in files and name.startswith("_") and not name.startswith("__")]
    assert found == []


def private_module_imports(path: Path, module: str) -> list[str]:
    """Imports in ``path`` (module ``module``) of a private module (``_x.py``) of a package other than
    the importer's own: ``pkg._x`` may be imported only by modules inside ``pkg``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = []
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # ``from pkg import _x`` names a private module when pkg/_x.py exists (a private name
            # of a module is the rule above's)
            targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names
                                       if f"{node.module}.{a.name}" in _modules()]
        for target in targets:
            parts = target.split(".")
            if parts[0] not in ("ofbe_data", "ofbe_model"):
                continue
            private = next((i for i, part in enumerate(parts) if part.startswith("_")
                            and not part.startswith("__")), None)
            if private is None:
                continue
            package = ".".join(parts[:private])
            if module != package and not module.startswith(package + "."):
                out.append(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{node.lineno}: "
                           f"imports {target}, private to {package}")
    return out


@functools.cache
def _modules() -> frozenset[str]:
    """Every module of ours, dotted."""
    return frozenset(_module_name(p) for p in _sources("ofbe_data", "ofbe_model"))


def test_a_private_module_is_imported_only_from_its_own_package() -> None:
    """``pkg/_x.py`` is behind ``pkg/__init__.py``: nothing outside ``pkg`` imports it (tests of the
    package's internals aside)."""
    found = [v for p in _sources("ofbe_data", "ofbe_model", "pipelines", "benchmarks")
             for v in private_module_imports(p, _module_name(p))]
    assert _modules() >= {"ofbe_data.io.detection._sniff", "ofbe_data.io.detection._session"}
    assert found == []


@pytest.mark.parametrize(("source", "module", "bad"), [
    ("from ofbe_data.io.detection._layout import TextLines\n", "ofbe_data.cli.session", True),
    ("from ofbe_data.io.detection import _layout\n", "ofbe_data.freeliving.raw", True),
    ("def f():\n    import ofbe_data.io.detection._units\n", "ofbe_data.io.manifest", True),
    ("from ofbe_data.io.detection._units import fmt_num\n", "ofbe_data.io.detection._result", False),
    ("from ofbe_data.io.detection import sniff_text\n", "ofbe_data.cli.session", False),
])
def test_a_private_module_imported_from_outside_is_reported(tmp_path: Path, source: str, module: str,
                                                            bad: bool) -> None:
    path = tmp_path / "m.py"
    path.write_text(source)
    found = private_module_imports(path, module)
    assert len(found) == int(bad) and all("private to ofbe_data.io.detection" in f for f in found)


def test_no_import_cycle_between_files() -> None:
    graph = _graph()
    cycles: list[list[str]] = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert [" -> ".join(c) for c in cycles] == []


def test_every_package_says_what_it_holds_and_may_import() -> None:
    for init in _sources("ofbe_data", "ofbe_model"):
        if init.name != "__init__.py":
            continue
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and "import" in doc, init.relative_to(ROOT)


@pytest.mark.parametrize(("registry", "doc"), [
    ("ofbe_data.io.formats:format_names", "docs/formats.md"),
    ("ofbe_model.estimators:estimator_names", "docs/estimators.md"),
    ("ofbe_data.calibration.exports:export_names", "docs/exports.md"),
])
def test_the_docs_name_every_registered_member(registry: str, doc: str) -> None:
    import importlib

    module, name = registry.split(":")
    members = getattr(importlib.import_module(module), name)
    names = tuple(members() if callable(members) else members)
    text = (ROOT / doc).read_text(encoding="utf-8")
    assert names and [n for n in names if f"`{n}`" not in text] == []
