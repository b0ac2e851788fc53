"""Labelling-side code must never open the simulator's _truth/ folder."""

from __future__ import annotations

import builtins
import io
import pathlib
from pathlib import Path

import pytest

import ofbe_data
from ofbe_data.labelling.labels import LabelParams, label_session

SIMULATOR_ONLY = {"simulator", "simulate.py"}
#: Outside the simulator and its command, only label fidelity reads truth files (for dataset
#: cards), and the reports show its results; never for labels.
TRUTH_READERS = {"fidelity.py", "reports"}


@pytest.mark.slow
def test_labelling_does_not_open_truth_files(examples, monkeypatch):
    opened: list[str] = []
    real_open, real_io_open = builtins.open, io.open
    real_read_bytes, real_read_text = pathlib.Path.read_bytes, pathlib.Path.read_text

    def spy_open(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    def spy_io_open(file, *args, **kwargs):
        opened.append(str(file))
        return real_io_open(file, *args, **kwargs)

    def spy_read_bytes(self):
        opened.append(str(self))
        return real_read_bytes(self)

    def spy_read_text(self, *args, **kwargs):
        opened.append(str(self))
        return real_read_text(self, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", spy_open)
    monkeypatch.setattr(io, "open", spy_io_open)
    monkeypatch.setattr(pathlib.Path, "read_bytes", spy_read_bytes)
    monkeypatch.setattr(pathlib.Path, "read_text", spy_read_text)
    n_files = 0
    for manifest_path in sorted(examples.glob("*/*/session.yaml")):
        labels = label_session(manifest_path.parent, LabelParams(min_samples=500))
        n_files += len(labels.files) - 1  # the manifest is hashed too
    assert n_files == 37  # every file of every example session, the continuous Ferraris file included
    assert any(p.endswith("session.yaml") for p in opened)
    assert not [p for p in opened if "_truth" in p]


def test_no_labelling_module_mentions_truth():
    package = Path(ofbe_data.__file__).parent
    offenders = [str(p.relative_to(package)) for p in package.rglob("*.py")
                 if not (SIMULATOR_ONLY | TRUTH_READERS) & set(p.relative_to(package).parts)
                 and "_truth" in p.read_text(encoding="utf-8")]
    assert offenders == []
