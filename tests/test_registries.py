"""One registry per extension point, every list derived from it: a toy device format and a toy
estimator, registered here and removed afterwards, appear in every list that names the formats
or the estimators (manifest validation, ``init``'s detection, the reference formats of ``init``
and the simulator, the docs test's names; the benchmark's default methods)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ofbe_data.core.errors import ManifestError
from ofbe_data.io.detection import sniff_text
from ofbe_data.io.device_options import CsvMapping, DeviceSpec
from ofbe_data.io.formats import (
    Format,
    Sniffed,
    format_names,
    formats,
    read_device_file,
    reference_formats,
    register_format,
    unregister_format,
)
from ofbe_data.io.formats.generic_csv import read_generic_csv
from ofbe_data.io.manifest import format_choices, load_manifest
from ofbe_data.io.recording import Recording
from ofbe_data.simulator.config import load_config
from ofbe_model.benchmark.runner import BenchmarkParams, default_methods
from ofbe_model.estimators import (
    Estimator,
    estimator_names,
    make_estimator,
    register,
    registered_names,
    unregister,
)

TOY = "toy-logger"
TOY_MAPPING = CsvMapping(columns={"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, skip_rows=1)


def _read_toy(path: Path, device: DeviceSpec) -> Recording:
    return read_generic_csv(path, TOY_MAPPING, device.id)


def _sniff_toy(lines: Sequence[str], i: int) -> Sniffed | None:
    if not lines[i].startswith("# toy-logger"):
        return None
    return Sniffed(evidence=f"'# toy-logger' header at line {i + 1}", model="TOY-1",
                   model_evidence="the toy's own header")


@pytest.fixture
def toy_format() -> Iterator[Format]:
    fmt = register_format(Format(name=TOY, reader=_read_toy, reference=True,
                                 signature="'# toy-logger' header", sniff=_sniff_toy))
    try:
        yield fmt
    finally:
        unregister_format(TOY)
    assert TOY not in format_names()


def _toy_file(path: Path, n: int = 200) -> Path:
    t = np.arange(n) / 100.0
    rows = "".join(f"{x:.2f},0.01,-0.02,9.81\n" for x in t)
    path.write_text("# toy-logger v1\nt,ax,ay,az\n" + rows)
    return path


def _manifest(folder: Path, fmt: str) -> Path:
    _toy_file(folder / "rec-01.csv")
    (folder / "session.yaml").write_text(textwrap.dedent(f"""\
        format: ofbe-session/1
        campaign: c
        session: s
        kind: gravity-aligned
        site: {{gravity_mps2: 9.8}}
        power_cycle: 1
        devices:
          toy:
            model: TOY-1
            role: dut
            format: {fmt}
        recordings:
          - id: rec-01
            files: {{toy: rec-01.csv}}
        """))
    return folder / "session.yaml"


def test_the_built_in_formats_in_registration_order() -> None:
    assert [f.name for f in formats()] == ["ofbe-logger", "mscip-csv", "mscip-bin", "csv"]
    assert format_choices() == ("ofbe-logger", "mscip-csv", "mscip-bin", "csv")
    assert reference_formats() == ("mscip-csv", "mscip-bin")
    assert format_names() == ("csv", "mscip-bin", "mscip-csv", "ofbe-logger")


def test_a_registered_format_is_one_the_manifest_takes(tmp_path: Path, toy_format: Format) -> None:
    m = load_manifest(_manifest(tmp_path, TOY))
    assert m.devices["toy"].format == TOY
    rec = read_device_file(m.file_path(m.recordings[0], "toy"), m.devices["toy"])
    assert rec.n == 200 and rec.fs_hz == pytest.approx(100.0)
    with pytest.raises(ManifestError) as exc:
        load_manifest(_manifest(tmp_path, "toy-loger"))
    assert "expected one of ofbe-logger, mscip-csv, mscip-bin, csv, toy-logger" in str(exc.value)


def test_without_the_registration_the_manifest_refuses_it(tmp_path: Path) -> None:
    with pytest.raises(ManifestError) as exc:
        load_manifest(_manifest(tmp_path, TOY))
    assert str(exc.value).endswith("devices.toy.format: expected one of ofbe-logger, mscip-csv, mscip-bin, "
                                   "csv, found str 'toy-logger'")


def test_init_recognises_a_registered_format_by_its_sniffer(tmp_path: Path, toy_format: Format) -> None:
    det = sniff_text(_toy_file(tmp_path / "a.csv"))
    assert det.format == TOY and det.model == "TOY-1"
    assert [(d.key, d.value, d.evidence) for d in det.decisions[:2]] == [
        ("format", TOY, "'# toy-logger' header at line 1"), ("model", "TOY-1", "the toy's own header")]
    assert det.rate_hz == pytest.approx(100.0)  # read back through the toy's reader
    plain = tmp_path / "plain.csv"
    plain.write_text("t,ax,ay,az\n" + "".join(f"{k / 100:.2f},0.01,-0.02,9.81\n" for k in range(200)))
    generic = sniff_text(plain)
    assert generic.format == "csv"
    assert generic.decisions[0].evidence == ("no '# ofbe-logger' header and no MSCIP export lines and no "
                                             "'# toy-logger' header: a generic csv")


def test_without_the_registration_init_takes_it_for_a_generic_csv(tmp_path: Path) -> None:
    det = sniff_text(_toy_file(tmp_path / "a.csv"))
    assert det.format == "csv"
    assert det.decisions[0].evidence == "no '# ofbe-logger' header and no MSCIP export lines: a generic csv"


def test_a_reference_format_is_one_the_simulator_and_init_take(toy_format: Format) -> None:
    assert reference_formats() == ("mscip-csv", "mscip-bin", TOY)
    assert load_config("tiny-rotated", {"reference_format": TOY}).reference_format == TOY


def test_the_docs_test_names_a_registered_format(toy_format: Format) -> None:
    """tests/test_architecture.py checks the names of ``format_names()`` against docs/formats.md: the
    toy is among them (and undocumented)."""
    docs = (Path(__file__).resolve().parents[1] / "docs" / "formats.md").read_text(encoding="utf-8")
    assert TOY in format_names() and [n for n in format_names() if f"`{n}`" not in docs] == [TOY]


class ToyMean(Estimator):
    """The mean window minus gravity along z: a toy."""

    name = "toy-mean"

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        mean = np.asarray(windows, dtype=np.float64).mean(axis=1)
        return mean - np.outer(np.asarray(meta["g_local"], dtype=np.float64), [0.0, 0.0, 1.0])


@pytest.fixture
def toy_estimator() -> Iterator[type[Estimator]]:
    cls = register(ToyMean)
    try:
        yield cls
    finally:
        unregister(ToyMean.name)
    assert ToyMean.name not in estimator_names()


def test_the_built_in_estimators_give_the_default_methods() -> None:
    assert registered_names() == ("level-mean", "ls-trf", "won2009", "prior-mean", "gravity-prior", "ofbenet",
                                  "oracle")
    assert BenchmarkParams().methods == default_methods() == (
        "level-mean", "ls-trf", "ls-trf-as-written", "ls-trf-bounded", "won2009", "prior-mean",
        "gravity-prior", "gravity-prior-direction", "ofbenet", "oracle")


def test_a_registered_estimator_is_one_the_benchmark_runs_by_default(toy_estimator: type[Estimator]) -> None:
    assert "toy-mean" in estimator_names()
    assert default_methods()[-1] == "toy-mean" and BenchmarkParams().methods[-1] == "toy-mean"
    windows = np.tile([0.1, -0.2, 9.9], (2, 50, 1))
    meta = pd.DataFrame({"device": ["d", "d"], "g_local": [9.8, 9.8]})
    np.testing.assert_allclose(make_estimator("toy-mean").predict(windows, meta), [[0.1, -0.2, 0.1]] * 2,
                               atol=1e-12)


def test_the_estimator_names_list_ofbenet_without_starting_tensorflow() -> None:
    code = ("import sys, ofbe_model.estimators as e; "
            "print('ofbenet' in e.estimator_names(), 'tensorflow' in sys.modules, 'keras' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         check=True)
    assert out.stdout.split() == ["True", "False", "False"]
