"""One registry per extension point, every list derived from it: a toy device format and a toy
estimator, registered here and removed afterwards, appear in every list that names the formats
or the estimators (manifest validation, ``init``'s detection, the reference formats of ``init``
and the simulator, the docs test's names; the benchmark's default methods). And adding one is its
own file: a toy format, estimator or export module dropped into a copy of its package is found
with no other file edited (:func:`ofbe_data.core.plugins.import_submodules`)."""

from __future__ import annotations

import os
import shutil
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
from tests.helpers.paths import ROOT

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


BUILT_IN_FORMATS = ("ofbe-logger", "mscip-csv", "mscip-bin", "csv")


def _built_in(names: Sequence[str], built_in: Sequence[str]) -> list[str]:
    """``names`` without those a newer module added: the built-in ones, in the order listed."""
    return [n for n in names if n in built_in]


def test_the_built_in_formats_in_their_order() -> None:
    # a format module added later joins these lists; the built-in ones keep their order
    assert _built_in([f.name for f in formats()], BUILT_IN_FORMATS) == list(BUILT_IN_FORMATS)
    assert format_choices() == tuple(f.name for f in formats()) and format_choices()[-1] == "csv"
    assert _built_in(reference_formats(), BUILT_IN_FORMATS) == ["mscip-csv", "mscip-bin"]
    assert format_names() == tuple(sorted(format_choices()))


def test_a_registered_format_is_one_the_manifest_takes(tmp_path: Path, toy_format: Format) -> None:
    m = load_manifest(_manifest(tmp_path, TOY))
    assert m.devices["toy"].format == TOY
    rec = read_device_file(m.file_path(m.recordings[0], "toy"), m.devices["toy"])
    assert rec.n == 200 and rec.fs_hz == pytest.approx(100.0)
    with pytest.raises(ManifestError) as exc:
        load_manifest(_manifest(tmp_path, "toy-loger"))
    # a format left at the default order comes after the built-in ones, before the generic csv
    assert f"expected one of {', '.join(format_choices())}," in str(exc.value)
    assert format_choices()[-2:] == (TOY, "csv")


def test_without_the_registration_the_manifest_refuses_it(tmp_path: Path) -> None:
    with pytest.raises(ManifestError) as exc:
        load_manifest(_manifest(tmp_path, TOY))
    assert TOY not in format_choices()
    assert str(exc.value).endswith(f"devices.toy.format: expected one of {', '.join(format_choices())}, "
                                   "found str 'toy-logger'")


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
    evidence = generic.decisions[0].evidence
    assert evidence.startswith("no '# ofbe-logger' header and no MSCIP export lines and no ")
    assert evidence.endswith(" and no '# toy-logger' header: a generic csv")


def test_without_the_registration_init_takes_it_for_a_generic_csv(tmp_path: Path) -> None:
    det = sniff_text(_toy_file(tmp_path / "a.csv"))
    assert det.format == "csv"
    evidence = det.decisions[0].evidence
    assert evidence.startswith("no '# ofbe-logger' header and no MSCIP export lines")
    assert evidence.endswith(": a generic csv") and "toy-logger" not in evidence


def test_a_reference_format_is_one_the_simulator_and_init_take(toy_format: Format) -> None:
    assert _built_in(reference_formats(), (*BUILT_IN_FORMATS, TOY)) == ["mscip-csv", "mscip-bin", TOY]
    assert load_config("tiny-rotated", {"reference_format": TOY}).reference_format == TOY


def test_the_docs_test_names_a_registered_format(toy_format: Format) -> None:
    """tests/test_architecture.py checks the names of ``format_names()`` against docs/formats.md: the
    toy is among them (and undocumented)."""
    docs = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
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


BUILT_IN_METHODS = ("level-mean", "ls-trf", "ls-trf-as-written", "ls-trf-bounded", "won2009", "prior-mean",
                    "gravity-prior", "gravity-prior-direction", "ofbenet", "oracle")


def test_the_built_in_estimators_give_the_default_methods() -> None:
    # an estimator module added later joins these lists; the built-in ones keep their order
    assert _built_in(registered_names(), BUILT_IN_METHODS) == [
        "level-mean", "ls-trf", "won2009", "prior-mean", "gravity-prior", "ofbenet", "oracle"]
    assert BenchmarkParams().methods == default_methods()
    assert _built_in(default_methods(), BUILT_IN_METHODS) == list(BUILT_IN_METHODS)
    assert default_methods()[-1] == "oracle"


def test_a_registered_estimator_is_one_the_benchmark_runs_by_default(toy_estimator: type[Estimator]) -> None:
    assert "toy-mean" in estimator_names()
    # an estimator left at the default order comes after the built-in ones, before the oracle
    assert default_methods()[-2:] == BenchmarkParams().methods[-2:] == ("toy-mean", "oracle")
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


# -- extension by one file: a module dropped into a copy of the package ---------------------------


def _copy_with(tmp_path: Path, package: str, files: dict[str, str]) -> Path:
    """A copy of ``package`` (ofbe_data or ofbe_model) under ``tmp_path`` with ``files`` (path
    inside the package → text) added; put ``tmp_path`` first on PYTHONPATH to import it."""
    shutil.copytree(ROOT / package, tmp_path / package, ignore=shutil.ignore_patterns("__pycache__"))
    for rel, text in files.items():
        (tmp_path / package / rel).write_text(textwrap.dedent(text))
    return tmp_path


def _run(path: Path, code: str) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                         timeout=600, cwd=path, env={**env, "PYTHONPATH": str(path)})
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines()


def test_a_format_module_dropped_into_the_package_is_a_format(tmp_path: Path) -> None:
    root = _copy_with(tmp_path, "ofbe_data", {"io/formats/toy_logger.py": '''
        from ofbe_data.io.formats.generic_csv import read_generic_csv
        from ofbe_data.io.device_options import CsvMapping
        from ofbe_data.io.formats.registry import Format, register_format

        M = CsvMapping(columns={"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, skip_rows=1)
        register_format(Format(name="toy-logger", reader=lambda path, d: read_generic_csv(path, M, d.id),
                               reference=True))
        '''})
    out = _run(root, """
        import ofbe_data.io.formats as f
        from ofbe_data.io.manifest import format_choices
        print(f.__file__)
        print(*format_choices())
        print(*f.reference_formats())
        """)
    assert out[0] == str(root / "ofbe_data" / "io" / "formats" / "__init__.py")
    listed, reference = out[1].split(), out[2].split()
    assert _built_in(listed, (*BUILT_IN_FORMATS, "toy-logger")) == ["ofbe-logger", "mscip-csv", "mscip-bin",
                                                                     "toy-logger", "csv"]
    assert listed[-2:] == ["toy-logger", "csv"] and reference[-1] == "toy-logger"


def test_an_estimator_module_dropped_into_the_package_is_a_default_method(tmp_path: Path) -> None:
    root = _copy_with(tmp_path, "ofbe_model", {"estimators/toy_mean.py": '''
        from typing import ClassVar
        from ofbe_model.estimators.base import Estimator, register

        @register
        class ToyMean(Estimator):
            name: ClassVar[str] = "toy-mean"
            order: ClassVar[int] = 15

            def predict(self, windows, meta):
                return windows.mean(axis=1)
        '''})
    out = _run(root, """
        from ofbe_model.benchmark.runner import default_methods
        print(*default_methods())
        """)
    assert _built_in(out[0].split(), (*BUILT_IN_METHODS, "toy-mean")) == [
        "level-mean", "toy-mean", "ls-trf", "ls-trf-as-written", "ls-trf-bounded", "won2009", "prior-mean",
        "gravity-prior", "gravity-prior-direction", "ofbenet", "oracle"]


def test_an_export_module_dropped_into_the_package_is_a_command(tmp_path: Path) -> None:
    root = _copy_with(tmp_path, "ofbe_data", {"calibration/exports/toy_txt.py": '''
        from ofbe_data.calibration.output import ExportFile
        from ofbe_data.calibration.registry import Format

        FORMAT = Format(lambda args: [], "a toy text file", examples=("ofbe-export toy SOURCE --out x/",),
                        name="toy", order=45)
        '''})
    out = _run(root, """
        import sys
        from ofbe_data.calibration.exports import CALIBRATION_FORMATS
        from ofbe_data.cli.export import main
        print(*CALIBRATION_FORMATS)
        sys.argv = ["ofbe-export", "toy", "--help"]
        main()
        """)
    assert _built_in(out[0].split(), ("imucal", "kalibr", "ros", "ggir", "toy", "json")) == [
        "imucal", "kalibr", "ros", "ggir", "toy", "json"]
    assert "a toy text file" in out and "  ofbe-export toy SOURCE --out x/" in out


def test_every_public_module_is_imported_in_name_order(tmp_path: Path) -> None:
    pkg = tmp_path / "toypkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from ofbe_data.core.plugins import import_submodules\n"
                                     "SEEN = []\nMODULES = import_submodules(__name__)\n")
    for name in ("b", "a", "_private"):
        (pkg / f"{name}.py").write_text(f"from toypkg import SEEN\nSEEN.append({name!r})\n")
    (pkg / "sub" / "__init__.py").write_text("from toypkg import SEEN\nSEEN.append('sub')\n")
    out = _run(tmp_path, """
        import toypkg
        print(*toypkg.SEEN)
        print(*(m.__name__ for m in toypkg.MODULES))
        """)
    assert out == ["a b", "toypkg.a toypkg.b"]
