"""The packages' front doors: what ``help()`` shows a notebook user, and that it works."""

from __future__ import annotations

import pydoc
import subprocess
import sys
from pathlib import Path

import pytest

import ofbe_data
import ofbe_model

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("package", [ofbe_data, ofbe_model], ids=lambda p: p.__name__)
def test_help_lists_every_front_door_name_with_its_own_docstring(package) -> None:
    text = pydoc.render_doc(package, renderer=pydoc.plaintext)
    for name in package.__all__:
        if name == "__version__":
            continue
        value = getattr(package, name)
        assert value.__module__.startswith(package.__name__ + "."), name
        first = (value.__doc__ or "").strip().splitlines()[0]
        assert first and first in text, f"help({package.__name__}) does not show {name}: {first!r}"


@pytest.mark.parametrize("package", ["ofbe_data", "ofbe_model"])
def test_importing_the_package_imports_no_heavy_library(package: str) -> None:
    code = (f"import sys, {package}; heavy = [m for m in ('tensorflow', 'keras', 'pandas', 'scipy', "
            f"'h5py', 'matplotlib') if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         timeout=180)
    assert out.stdout.strip() == ""


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="module 'ofbe_data' has no attribute 'label_sessions'"):
        ofbe_data.label_sessions  # noqa: B018
    with pytest.raises(AttributeError, match="module 'ofbe_model' has no attribute 'train'"):
        ofbe_model.train  # noqa: B018


def test_the_front_door_example_labels_a_committed_session() -> None:
    folder = ROOT / "raw/examples/tiny-multi-position/mp-pc001"
    session = ofbe_data.load_manifest(folder)
    labels = ofbe_data.label_session(folder)
    assert session.kind == "multi-position"
    assert len(labels.rows) == 16
    assert {row["device"] for row in labels.rows} == {dev.id for dev in session.duts}
    est = ofbe_model.make_estimator("level-mean")
    assert est.__class__.__name__ and "gravity-prior" in ofbe_model.estimator_names()
