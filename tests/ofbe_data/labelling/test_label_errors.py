"""Bad inputs to labelling (raw-formats.md, products.md): every one ends in its exact error
(naming the file and line) or its exact rejection, nothing partial is left behind, a bad
session never stops the others, and garbled logs never crash the labeller.

Sessions are copies of raw/examples in tmp_path; raw/ itself is never touched. DUT files
that need exact line numbers are rewritten with ``write_ofbe_logger`` first (no boot lines:
the column line is line 4 and sample k sits on line ``5 + k``).
"""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ofbe_data.cli.label import main
from ofbe_data.core.errors import ManifestError, OfbeError, RawFormatError
from ofbe_data.io.formats.mscip_csv import read_mscip_csv
from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger, write_ofbe_logger
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import format_choices, load_manifest
from ofbe_data.io.recording import SkippedLine
from ofbe_data.labelling.labels import LabelParams, label_session
from ofbe_data.labelling.store import read_labels
from tests.helpers.paths import ROOT

EXAMPLES = ROOT / "raw" / "examples"
GA = "tiny-gravity-aligned/ga-pc001"
ROT = "tiny-rotated/rot-pc001"
MP = "tiny-multi-position/mp-pc001"
IMUCAL = "imucal-ferraris/ferraris-pc001"
PARAMS = LabelParams(min_samples=1000)
DATA_LINE = 5  # first data line of a file rewritten by _rewrite_logger
MSCIP_DATA_LINE = 7  # first data line of the example Memsense exports


# --------------------------------------------------------------------------- helpers


def _copy(tmp_path: Path, name: str) -> Path:
    """A private copy of an example session (raw/ is never modified)."""
    dst = tmp_path / "raw" / name
    shutil.copytree(EXAMPLES / name, dst)
    return dst


def _lines(path: Path) -> list[bytes]:
    return path.read_bytes().split(b"\n")


def _write_lines(path: Path, lines: list[bytes]) -> None:
    path.write_bytes(b"\n".join(lines))


def _rewrite_logger(path: Path, counts_fn: Callable[[np.ndarray], np.ndarray] | None = None,
                    corrupt: Callable[[list[bytes]], list[bytes]] | None = None,
                    keep: int | None = None) -> int:
    """Rewrite an ofbe-logger file through the writer (same samples, no boot lines, no
    garbled lines), optionally changing counts or corrupting data lines. Returns the number
    of samples written."""
    rec = read_ofbe_logger(path)
    t_us = np.rint(rec.t * 1e6).astype(np.int64)
    counts = np.rint(rec.acc / G0 * float(rec.header["lsb_per_g"])).astype(np.int64)
    if counts_fn is not None:
        counts = counts_fn(counts.copy())
    if keep is not None:
        t_us, counts = t_us[:keep], counts[:keep]
    write_ofbe_logger(path, t_us, counts, rec.header, (), corrupt)
    return int(t_us.shape[0])


def _edit_mscip(path: Path, fn: Callable[[int, list[bytes]], list[bytes]]) -> None:
    """Apply ``fn(line_number, fields)`` to every data line of a Memsense export."""
    lines = _lines(path)
    for i in range(MSCIP_DATA_LINE - 1, len(lines)):
        if lines[i]:
            lines[i] = b",".join(fn(i + 1, lines[i].split(b",")))
    _write_lines(path, lines)


def _run(capsys, *args: object) -> tuple[int, str]:
    rc = main([str(a) for a in args])
    return rc, capsys.readouterr().err


def _label_cli(capsys, out: Path, *sessions: Path, min_samples: int = 1000) -> tuple[int, str]:
    return _run(capsys, *sessions, "--out", out, "--min-samples", min_samples, "--quiet")


def _files(out: Path) -> list[str]:
    """Every file under ``out`` (temporary files included), relative, sorted."""
    if not out.exists():
        return []
    return sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())


def _session_files(campaign: str, *sessions: str) -> list[str]:
    names = [f"{campaign}/campaign_fit.json"]
    for s in sessions:
        names += [f"{campaign}/{s}.parquet", f"{campaign}/{s}.rejected.json"]
    return sorted(names)


def _label_ok(capsys, tmp_path: Path, session: Path, min_samples: int = 1000):
    """Label one session through the CLI, which must succeed and write exactly its three
    files; returns the label frame and the rejections."""
    out = tmp_path / "out"
    assert _label_cli(capsys, out, session, min_samples=min_samples) == (0, "")
    m = load_manifest(session)
    assert _files(out) == _session_files(m.campaign, m.session)
    labels = read_labels(out / m.campaign / f"{m.session}.parquet")
    doc = json.loads((out / m.campaign / f"{m.session}.rejected.json").read_text(encoding="utf-8"))
    assert doc["labelled"] == len(labels)
    return labels, doc["rejected"]


def _ids(labels) -> list[tuple[str, str]]:
    return list(zip(labels["recording"], labels["device"], strict=True))


def _rejection(recording: str, device: str, reason: str, detail: str) -> dict[str, str]:
    return {"recording": recording, "device": device, "reason": reason, "detail": detail}


def _bias(labels, recording: str, device: str) -> np.ndarray:
    row = labels[(labels["recording"] == recording) & (labels["device"] == device)]
    assert len(row) == 1
    return row[["bias_x", "bias_y", "bias_z"]].to_numpy()[0]


def _clean_bias(name: str, recording: str, device: str) -> np.ndarray:
    row = next(r for r in label_session(EXAMPLES / name, PARAMS).rows
               if (r["recording"], r["device"]) == (recording, device))
    return np.array([row["bias_x"], row["bias_y"], row["bias_z"]])


# --------------------------------------------------------------------------- unreadable files


def _unlink(path: Path) -> None:
    path.unlink()


def _empty(path: Path) -> None:
    path.write_bytes(b"")


def _boot_noise_only(path: Path) -> None:
    _write_lines(path, [*_lines(path)[:2], b""])


def _logger_header_only(path: Path) -> None:
    _rewrite_logger(path, keep=0)


def _logger_header_only_no_final_newline(path: Path) -> None:
    _rewrite_logger(path, keep=0)
    path.write_bytes(path.read_bytes().rstrip(b"\n"))


def _logger_field_count_everywhere(path: Path) -> None:
    _rewrite_logger(path, corrupt=lambda lines: [line + b",0" for line in lines])


def _logger_nan_everywhere(path: Path) -> None:
    _rewrite_logger(path, corrupt=lambda lines: [line.split(b",")[0] + b",nan,0,256" for line in lines])


def _logger_missing_column(path: Path) -> None:
    _rewrite_logger(path)
    path.write_bytes(path.read_bytes().replace(b"t_us,ax,ay,az\n", b"t_us,ax,ay\n"))


def _logger_without_lsb(path: Path) -> None:
    _rewrite_logger(path)
    path.write_bytes(path.read_bytes().replace(b" lsb_per_g=256", b""))


def _logger_zero_lsb(path: Path) -> None:
    _rewrite_logger(path)
    path.write_bytes(path.read_bytes().replace(b" lsb_per_g=256", b" lsb_per_g=0"))


def _mscip_header_only(path: Path) -> None:
    _write_lines(path, [*_lines(path)[:MSCIP_DATA_LINE - 1], b""])


def _mscip_field_count_everywhere(path: Path) -> None:
    _edit_mscip(path, lambda n, f: f[:5])


def _mscip_inf_everywhere(path: Path) -> None:
    _edit_mscip(path, lambda n, f: [*f[:4], b"inf", *f[5:]])


NO_DATA = "{file}:4: expected at least one valid data line, found none"

FILE_ERRORS = [
    pytest.param(GA, "rec-01/sparkfun-1.csv", _unlink,
                 "{file}: expected a readable data file, found no such file", id="missing-dut-file"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _empty,
                 "{file}: expected a '# ofbe-logger' header line, found none in the file",
                 id="empty-dut-file"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _boot_noise_only,
                 "{file}: expected a '# ofbe-logger' header line, found none in the file",
                 id="boot-noise-only"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_header_only, NO_DATA, id="dut-header-only"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_header_only_no_final_newline, NO_DATA,
                 id="dut-header-only-without-final-newline"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_field_count_everywhere, NO_DATA,
                 id="dut-wrong-field-count-on-every-line"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_nan_everywhere, NO_DATA,
                 id="dut-nan-on-every-line"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_missing_column,
                 "{file}:4: expected columns t_us, ax, ay, az, found 't_us,ax,ay' (missing az)",
                 id="dut-missing-column"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_without_lsb,
                 "{file}:1: expected header key lsb_per_g=<number>, found no such key",
                 id="dut-header-without-lsb_per_g"),
    pytest.param(GA, "rec-01/sparkfun-1.csv", _logger_zero_lsb,
                 "{file}:1: expected header key lsb_per_g > 0, found '0'", id="dut-lsb_per_g-zero"),
    pytest.param(ROT, "rec-01/memsense.csv", _unlink,
                 "{file}: expected a readable data file, found no such file",
                 id="missing-reference-file"),
    pytest.param(ROT, "rec-01/memsense.csv", _empty,
                 "{file}: expected a column line starting with 'Time (s)', found none in the file",
                 id="empty-reference-file"),
    pytest.param(ROT, "rec-01/memsense.csv", _mscip_header_only,
                 "{file}:6: expected at least one valid data line, found none",
                 id="reference-header-only"),
    pytest.param(ROT, "rec-01/memsense.csv", _mscip_field_count_everywhere,
                 "{file}:6: expected at least one valid data line, found none",
                 id="reference-wrong-field-count-on-every-line"),
    pytest.param(ROT, "rec-01/memsense.csv", _mscip_inf_everywhere,
                 "{file}:6: expected at least one valid data line, found none",
                 id="reference-inf-on-every-line"),
]


@pytest.mark.parametrize(("name", "rel", "damage", "message"), FILE_ERRORS)
def test_unreadable_file_is_an_error_naming_file_and_line(tmp_path, capsys, name, rel, damage,
                                                          message):
    session = _copy(tmp_path, name)
    path = session / rel
    damage(path)
    expected = message.format(file=path)
    with pytest.raises(RawFormatError) as info:
        label_session(session, PARAMS)
    assert str(info.value) == expected
    out = tmp_path / "out"
    assert _label_cli(capsys, out, session) == (1, f"ofbe-label: error: {expected}\n")
    assert _files(out) == []


# --------------------------------------------------------------------------- bad manifests

YAML_PROBLEM = "(?:expected ',' or '\\]', but got ':'|did not find expected ',' or '\\]')"
GA_FILES = "files: {sparkfun-1: rec-01/sparkfun-1.csv, sparkfun-2: rec-01/sparkfun-2.csv}"

MANIFEST_ERRORS = [
    pytest.param(ROT, "  memsense: {model: MS-IMU3025, role: reference, format: mscip-csv}\n", "",
                 "{manifest}:7: devices: expected exactly one device with role reference for kind "
                 "rotated, found 0 (none)", id="rotated-without-reference"),
    pytest.param(ROT, "role: reference", "role: dut",
                 "{manifest}:7: devices: expected exactly one device with role reference for kind "
                 "rotated, found 0 (none)", id="rotated-reference-demoted-to-dut"),
    pytest.param(GA, "role: dut, format: ofbe-logger}\nrecordings",
                 "role: reference, format: ofbe-logger}\nrecordings",
                 "{manifest}:9: devices.sparkfun-2.role: expected no reference device for kind "
                 "gravity-aligned, found role reference", id="gravity-aligned-with-reference"),
    pytest.param(GA, GA_FILES, GA_FILES[:-1] + ", sparkfun-9: rec-01/sparkfun-9.csv}",
                 "{manifest}:13: recordings[0].files.sparkfun-9: expected a device declared under "
                 "devices (sparkfun-1, sparkfun-2), found unknown device 'sparkfun-9'",
                 id="undeclared-device"),
    pytest.param(GA, GA_FILES, "files: {sparkfun-1: rec-01/sparkfun-1.csv}",
                 "{manifest}:13: recordings[0].files: expected a file for declared device "
                 "'sparkfun-2', found no entry for it", id="declared-device-without-file"),
    # the problem's wording is the YAML parser's (PyYAML's or libyaml's)
    pytest.param(GA, "kind: gravity-aligned", "kind: [gravity-aligned",
                 "{manifest}:5: <document>: expected valid YAML, found {problem}",
                 id="yaml-syntax-error"),
    pytest.param(GA, "sparkfun-1: rec-01/sparkfun-1.csv", "sparkfun-1: ../sparkfun-1.csv",
                 "{manifest}:13: recordings[0].files.sparkfun-1: expected a path that stays inside "
                 "the session folder, found '../sparkfun-1.csv', which escapes it",
                 id="file-path-escapes-session"),
    pytest.param(GA, "format: ofbe-logger}\nrecordings", "format: adxl-raw}\nrecordings",
                 # every registered format, in their order (a new format module joins the list)
                 f"{{manifest}}:9: devices.sparkfun-2.format: expected one of {', '.join(format_choices())}, "
                 "found str 'adxl-raw'", id="unknown-device-format"),
]


@pytest.mark.parametrize(("name", "old", "new", "message"), MANIFEST_ERRORS)
def test_bad_manifest_is_an_error_naming_file_and_line(tmp_path, capsys, name, old, new, message):
    session = _copy(tmp_path, name)
    manifest = session / "session.yaml"
    text = manifest.read_text(encoding="utf-8")
    assert text.count(old) == 1
    manifest.write_text(text.replace(old, new), encoding="utf-8")
    head, problem, tail = message.partition("{problem}")
    expected = (re.escape(head.format(manifest=manifest)) + (YAML_PROBLEM if problem else "")
                + re.escape(tail))
    with pytest.raises(ManifestError) as info:
        label_session(session, PARAMS)
    assert re.fullmatch(expected, str(info.value))
    out = tmp_path / "out"
    rc, err = _label_cli(capsys, out, session)
    assert rc == 1 and re.fullmatch(f"ofbe-label: error: {expected}\n", err)
    assert _files(out) == []


# --------------------------------------------------------------------------- skipped lines


def test_a_few_lines_with_wrong_field_count_are_skipped_and_counted(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    path = session / "rec-01/sparkfun-1.csv"
    short, extra, lone = 100, 2000, 4000

    def corrupt(lines: list[bytes]) -> list[bytes]:
        lines[short] = b",".join(lines[short].split(b",")[:3])
        lines[extra] += b",12"
        lines[lone] = lines[lone].split(b",")[0]
        return lines

    n = _rewrite_logger(path, corrupt=corrupt)
    rec = read_ofbe_logger(path)
    assert rec.diagnostics.skipped == (
        SkippedLine(DATA_LINE + short, "field-count", "expected 4 fields, found 3"),
        SkippedLine(DATA_LINE + extra, "field-count", "expected 4 fields, found 5"),
        SkippedLine(DATA_LINE + lone, "field-count", "expected 4 fields, found 1"))
    assert (rec.n, rec.diagnostics.lines_read) == (n - 3, n)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == []
    assert _ids(labels) == [("rec-01", "sparkfun-1"), ("rec-01", "sparkfun-2")]
    assert labels["skipped_lines"].iloc[0] == 3
    np.testing.assert_allclose(_bias(labels, "rec-01", "sparkfun-1"),
                               _clean_bias(GA, "rec-01", "sparkfun-1"), atol=1e-3)


def test_many_lines_with_wrong_field_count_reject_the_recording_as_garbled(tmp_path, capsys):
    session = _copy(tmp_path, GA)

    def corrupt(lines: list[bytes]) -> list[bytes]:
        return [line + b",7" if i % 20 == 0 else line for i, line in enumerate(lines)]

    n = _rewrite_logger(session / "rec-01/sparkfun-1.csv", corrupt=corrupt)
    assert n == 5249
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == [_rejection("rec-01", "sparkfun-1", "garbled",
                                   "263 of 5249 data lines skipped (5.01% > 1.00%): 263 with the wrong "
                                   "number of fields")]
    assert _ids(labels) == [("rec-01", "sparkfun-2")]


NAN_TEXTS = {100: (1, b"nan"), 900: (2, b"inf"), 1700: (3, b"-inf"), 2500: (0, b"NaN"),
             3300: (1, b"Infinity")}


def _nan_lines(lines: list[bytes]) -> list[bytes]:
    for i, (col, text) in NAN_TEXTS.items():
        fields = lines[i].split(b",")
        fields[col] = text
        lines[i] = b",".join(fields)
    return lines


def test_a_few_nan_and_inf_values_are_skipped_and_never_reach_the_label(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    path = session / "rec-01/sparkfun-1.csv"
    _rewrite_logger(path, corrupt=_nan_lines)
    names = ("t_us", "ax", "ay", "az")
    assert read_ofbe_logger(path).diagnostics.skipped == tuple(
        SkippedLine(DATA_LINE + i, "non-numeric", f"field {names[col]!r} is not a number: "
                                                  f"'{text.decode()}'")
        for i, (col, text) in NAN_TEXTS.items())
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == []
    assert labels["skipped_lines"].iloc[0] == len(NAN_TEXTS)
    bias = _bias(labels, "rec-01", "sparkfun-1")
    assert np.all(np.isfinite(bias))
    np.testing.assert_allclose(bias, _clean_bias(GA, "rec-01", "sparkfun-1"), atol=1e-3)


def test_many_nan_values_reject_the_recording_as_garbled(tmp_path, capsys):
    session = _copy(tmp_path, GA)

    def corrupt(lines: list[bytes]) -> list[bytes]:
        return [line.split(b",")[0] + b",nan,nan,nan" if i % 50 == 7 else line
                for i, line in enumerate(lines)]

    _rewrite_logger(session / "rec-01/sparkfun-1.csv", corrupt=corrupt)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == [_rejection("rec-01", "sparkfun-1", "garbled",
                                   "105 of 5249 data lines skipped (2.00% > 1.00%): 105 not numeric")]
    assert _ids(labels) == [("rec-01", "sparkfun-2")]


def test_nan_and_inf_in_the_reference_are_skipped(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    path = session / "rec-01/memsense.csv"
    columns = {0: "Time (s)", 4: "Accel X (g)", 5: "Accel Y (g)", 6: "Accel Z (g)"}
    bad = {1000: (4, b"nan"), 1500: (5, b"inf"), 2000: (6, b"-inf"), 2500: (0, b"NaN")}
    _edit_mscip(path, lambda n, f: [bad[n][1] if i == bad[n][0] else x for i, x in enumerate(f)]
                if n in bad else f)
    assert read_mscip_csv(path).diagnostics.skipped == tuple(
        SkippedLine(n, "non-numeric", f"field {columns[col]!r} is not a number: '{text.decode()}'")
        for n, (col, text) in bad.items())
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == []
    assert len(labels) == 4
    for dev in ("sparkfun-1", "sparkfun-2"):
        np.testing.assert_allclose(_bias(labels, "rec-01", dev), _clean_bias(ROT, "rec-01", dev),
                                   atol=1e-3)


def test_overflowing_number_in_the_reference_is_skipped_not_read_as_inf(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    path = session / "rec-01/memsense.csv"
    _edit_mscip(path, lambda n, f: [*f[:4], b"1e999", *f[5:]] if n == 1627 else f)
    rec = read_mscip_csv(path)
    assert np.all(np.isfinite(rec.acc))
    assert [s.line for s in rec.diagnostics.skipped] == [1627]
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == []
    assert len(labels) == 4


def test_overflowing_number_in_a_generic_csv_is_skipped(tmp_path, capsys):
    session = _copy(tmp_path, IMUCAL)
    path = session / "rec-x_p/imu.csv"
    lines = _lines(path)
    fields = lines[400].split(b",")
    fields[1] = b"-2.052e999"
    lines[400] = b",".join(fields)
    _write_lines(path, lines)
    labels, rejected = _label_ok(capsys, tmp_path, session, min_samples=200)
    assert rejected == []
    assert len(labels) == 6


def test_explicit_plus_sign_in_counts_is_read(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    path = session / "rec-01/sparkfun-1.csv"

    def corrupt(lines: list[bytes]) -> list[bytes]:
        fields = lines[100].split(b",")
        fields[1] = b"+" + fields[1].lstrip(b"-")
        lines[100] = b",".join(fields)
        return lines

    n = _rewrite_logger(path, corrupt=corrupt)
    rec = read_ofbe_logger(path)
    assert (rec.n, rec.diagnostics.skipped) == (n, ())
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert (len(labels), rejected) == (2, [])


# --------------------------------------------------------------------------- non-monotonic time


def _backwards(start: int, length: int, seconds: float = 20.0):
    def corrupt(lines: list[bytes]) -> list[bytes]:
        for i in range(start, start + length):
            fields = lines[i].split(b",")
            fields[0] = str(int(fields[0]) - int(seconds * 1e6)).encode()
            lines[i] = b",".join(fields)
        return lines

    return corrupt


def test_a_short_block_of_backward_time_stamps_is_skipped(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    path = session / "rec-01/sparkfun-1.csv"
    n = _rewrite_logger(path, corrupt=_backwards(2000, 10))
    rec = read_ofbe_logger(path)
    assert [(s.line, s.kind) for s in rec.diagnostics.skipped] == [
        (DATA_LINE + i, "non-increasing-time") for i in range(2000, 2010)]
    assert (rec.n, rec.diagnostics.wraps) == (n - 10, 0)
    assert np.all(np.diff(rec.t) > 0)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == []
    assert labels["skipped_lines"].iloc[0] == 10


def test_a_long_block_of_backward_time_stamps_rejects_the_recording(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    path = session / "rec-01/sparkfun-1.csv"
    _rewrite_logger(path, corrupt=_backwards(2000, 200))
    rec = read_ofbe_logger(path)
    assert [(s.line, s.kind) for s in rec.diagnostics.skipped] == [
        (DATA_LINE + i, "non-increasing-time") for i in range(2000, 2200)]
    assert rec.diagnostics.wraps == 0
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == [_rejection("rec-01", "sparkfun-1", "garbled",
                                   "200 of 5249 data lines skipped (3.81% > 1.00%): 200 with a time "
                                   "stamp that repeats or runs backwards (duplicated lines, or rows not in "
                                   "time order: a file sorted by another column is read in time order with "
                                   "sort_by_time: true; the file itself is never changed)")]
    assert _ids(labels) == [("rec-01", "sparkfun-2")]


def test_a_long_block_of_backward_time_stamps_in_the_reference(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    path = session / "rec-01/memsense.csv"
    _edit_mscip(path, lambda n, f: [f"{float(f[0]) - 5:.6f}".encode(), *f[1:]]
                if 1627 <= n < 1727 else f)
    rec = read_mscip_csv(path)
    assert np.all(np.diff(rec.t) > 0)
    assert [s.line for s in rec.diagnostics.skipped] == list(range(1627, 1727))
    labels, rejected = _label_ok(capsys, tmp_path, session)
    detail = ("rec-01/memsense.csv: 100 of 3242 data lines skipped (3.08% > 1.00%): 100 with a time stamp "
              "that repeats or runs backwards (duplicated lines, or rows not in time order: a file sorted "
              "by another column is read in time order with sort_by_time: true; the file itself is never "
              "changed)")
    assert rejected == [_rejection("rec-01", d, "reference-garbled", detail)
                        for d in ("sparkfun-1", "sparkfun-2")]


# --------------------------------------------------------------------------- quality rejections

ROT_MID = 1204  # sample index in the middle of rec-01/sparkfun-1's stationary segment


def _oscillate(first: int, count: int, amplitude: int = 12, period: int = 30):
    def fn(counts: np.ndarray) -> np.ndarray:
        k = np.arange(count)
        counts[first:first + count, 0] += np.rint(amplitude * np.sin(2 * np.pi * k / period)
                                                  ).astype(np.int64)
        return counts

    return fn


def test_motion_in_the_stationary_segment_is_rejected(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    _rewrite_logger(session / "rec-01/sparkfun-1.csv", _oscillate(ROT_MID - 150, 300))
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == [_rejection(
        "rec-01", "sparkfun-1", "motion",
        "553 of 1595 samples in the stationary segment are moving (from line 933; moving-std "
        "peak 0.326 m/s² against a threshold of 0.146 m/s²)")]
    assert _ids(labels) == [("rec-01", "sparkfun-2"), ("rec-02", "sparkfun-1"), ("rec-02", "sparkfun-2")]


def test_saturated_samples_in_the_stationary_segment_are_rejected(tmp_path, capsys):
    session = _copy(tmp_path, ROT)

    def saturate(counts: np.ndarray) -> np.ndarray:
        counts[ROT_MID, 0] = 4095
        counts[ROT_MID + 7, 1] = -4096
        return counts

    _rewrite_logger(session / "rec-01/sparkfun-1.csv", saturate)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert rejected == [_rejection(
        "rec-01", "sparkfun-1", "saturated",
        f"2 saturated samples in the stationary segment (first at line {DATA_LINE + ROT_MID})")]
    assert _ids(labels) == [("rec-01", "sparkfun-2"), ("rec-02", "sparkfun-1"), ("rec-02", "sparkfun-2")]


def test_counts_beyond_the_converter_range_are_skipped_not_saturated(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    path = session / "rec-01/sparkfun-1.csv"

    def beyond(counts: np.ndarray) -> np.ndarray:
        counts[ROT_MID, 2] = -4097
        return counts

    _rewrite_logger(path, beyond)
    rec = read_ofbe_logger(path)
    row = rec.diagnostics.skipped
    assert len(row) == 1 and (row[0].line, row[0].kind) == (DATA_LINE + ROT_MID, "out-of-range")
    assert row[0].detail.endswith(", -4097] outside -4096..4095")
    labels, rejected = _label_ok(capsys, tmp_path, session)
    assert (len(labels), rejected) == (4, [])


@pytest.mark.slow
def test_a_saturated_sample_in_a_multi_position_recording_is_in_no_pose(tmp_path, capsys):
    session = _copy(tmp_path, MP)
    path = session / "rec-01/sparkfun-1.csv"
    rec = read_ofbe_logger(path)
    mid = rec.n // 2

    def saturate(counts: np.ndarray) -> np.ndarray:
        counts[mid, 0] = 4095
        return counts

    _rewrite_logger(path, saturate)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    # the pose detector sees the spike as handling: the still run is split around it, and no
    # labelled pose holds the saturated sample (a pose holding one would be rejected)
    assert rejected == []
    assert sorted(set(_ids(labels))) == [(f"rec-0{i}", "sparkfun-1") for i in range(1, 7)]
    spike_t = rec.t[mid]
    first = labels[labels["recording"] == "rec-01"]
    assert not ((first["segment_start_s"] <= spike_t) & (first["segment_end_s"] >= spike_t)).any()
    assert ((first["segment_end_s"] < spike_t).any() and (first["segment_start_s"] > spike_t).any())
    assert set(labels["label_method"]) == {"multi-position"}


def test_too_short_recordings_are_rejected_and_the_session_still_written(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    out = tmp_path / "out"
    # nothing labelled at all is not a success, but the session's rejection file is written (and no
    # label file of no label, issue 33)
    assert _label_cli(capsys, out, session, min_samples=5000) == (1, (
        f"ofbe-label: error: no recording was labelled (4 too-short; see the <session>.rejected.json files "
        f"in {out})\n"))
    m = load_manifest(session)
    assert _files(out) == [f"{m.campaign}/campaign_fit.json", f"{m.campaign}/{m.session}.rejected.json"]
    rejected = json.loads((out / m.campaign / f"{m.session}.rejected.json").read_text())["rejected"]
    assert rejected == [
        _rejection("rec-01", "sparkfun-1", "too-short", "1595 stationary samples, at least 5000 needed"),
        _rejection("rec-01", "sparkfun-2", "too-short", "1597 stationary samples, at least 5000 needed"),
        _rejection("rec-02", "sparkfun-1", "too-short", "1728 stationary samples, at least 5000 needed"),
        _rejection("rec-02", "sparkfun-2", "too-short", "1729 stationary samples, at least 5000 needed"),
    ]
    direct = label_session(session, LabelParams(min_samples=5000))
    assert [r.to_dict() for r in direct.rejections] == rejected and direct.rows == []


def test_reference_motion_rejects_every_dut_of_that_recording(tmp_path, capsys):
    session = _copy(tmp_path, ROT)

    def shake(n: int, f: list[bytes]) -> list[bytes]:
        if 1427 <= n < 1827:
            f[4] = f"{float(f[4]) + 0.05 * np.sin(2 * np.pi * (n - 1627) / 40):.5f}".encode()
        return f

    _edit_mscip(session / "rec-01/memsense.csv", shake)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    detail = ("rec-01/memsense.csv: 793 of 2131 samples in the stationary segment are moving (from "
              "line 1231; moving-std peak 0.348 m/s² against a threshold of 0.0173 m/s²)")
    assert rejected == [_rejection("rec-01", d, "reference-motion", detail)
                        for d in ("sparkfun-1", "sparkfun-2")]
    assert _ids(labels) == [("rec-02", "sparkfun-1"), ("rec-02", "sparkfun-2")]


def test_garbled_reference_rejects_every_dut_of_that_recording(tmp_path, capsys):
    session = _copy(tmp_path, ROT)
    _edit_mscip(session / "rec-01/memsense.csv", lambda n, f: f[:5] if 1327 <= n < 1427 else f)
    labels, rejected = _label_ok(capsys, tmp_path, session)
    detail = ("rec-01/memsense.csv: 100 of 3242 data lines skipped (3.08% > 1.00%): 100 with the wrong "
              "number of fields")
    assert rejected == [_rejection("rec-01", d, "reference-garbled", detail)
                        for d in ("sparkfun-1", "sparkfun-2")]
    assert _ids(labels) == [("rec-02", "sparkfun-1"), ("rec-02", "sparkfun-2")]


def _cut_reference_after_first_tap(session: Path) -> None:
    """Logging stopped 4 s in, just after the first tap (at 1.775 s)."""
    path = session / "rec-01/memsense.csv"
    _write_lines(path, [*_lines(path)[:MSCIP_DATA_LINE - 1 + 801], b""])


def test_reference_cut_short_after_one_tap_is_a_clean_rejection(tmp_path):
    session = _copy(tmp_path, ROT)
    _cut_reference_after_first_tap(session)
    labels = label_session(session, PARAMS)
    assert [(r["recording"], r["device"]) for r in labels.rows] == [("rec-02", "sparkfun-1"),
                                                                    ("rec-02", "sparkfun-2")]
    assert [(r.recording, r.device) for r in labels.rejections] == [("rec-01", "sparkfun-1"),
                                                                   ("rec-01", "sparkfun-2")]
    for r in labels.rejections:
        assert r.reason.startswith("reference-") and r.detail.startswith("rec-01/memsense.csv: ")


# --------------------------------------------------------------------------- batch mode


@pytest.mark.parametrize(("jobs", "as_campaign"), [(1, False), (2, True)])
def test_a_bad_session_does_not_stop_the_others(tmp_path, capsys, jobs, as_campaign):
    campaign = tmp_path / "raw" / "tiny-gravity-aligned"
    for s in ("ga-pc001", "ga-pc002", "ga-pc003"):
        shutil.copytree(EXAMPLES / "tiny-gravity-aligned" / s, campaign / s)
    bad = campaign / "ga-pc002" / "rec-01" / "sparkfun-2.csv"
    _rewrite_logger(bad, keep=0)
    out = tmp_path / "out"
    args = [campaign] if as_campaign else [campaign / s for s in ("ga-pc001", "ga-pc002", "ga-pc003")]
    rc, err = _run(capsys, *args, "--out", out, "--min-samples", 1000, "--quiet", "--jobs", jobs)
    assert (rc, err) == (1, f"ofbe-label: error: {bad}:4: expected at least one valid data line, "
                            "found none\n")
    assert _files(out) == _session_files("tiny-gravity-aligned", "ga-pc001", "ga-pc003")
    for s in ("ga-pc001", "ga-pc003"):
        assert len(read_labels(out / "tiny-gravity-aligned" / f"{s}.parquet")) == 2


def test_a_cleanly_rejecting_session_exits_zero_in_batch(tmp_path, capsys):
    good = _copy(tmp_path, GA)
    rejecting = _copy(tmp_path, ROT)
    rc, err = _run(capsys, good, rejecting, "--out", tmp_path / "out", "--min-samples", 5000,
                   "--quiet")
    assert (rc, err) == (0, "")
    assert _files(tmp_path / "out") == sorted(_session_files("tiny-gravity-aligned", "ga-pc001")
                                              + ["tiny-rotated/campaign_fit.json",
                                                 "tiny-rotated/rot-pc001.rejected.json"])  # no empty labels


def test_a_crashing_session_does_not_stop_the_others(tmp_path, capsys):
    good = _copy(tmp_path, GA)
    bad = _copy(tmp_path, ROT)
    _cut_reference_after_first_tap(bad)
    out = tmp_path / "out"
    rc, err = _label_cli(capsys, out, bad, good)
    assert (rc, err) == (0, "")
    assert _files(out) == sorted(_session_files("tiny-gravity-aligned", "ga-pc001")
                                 + _session_files("tiny-rotated", "rot-pc001"))


# --------------------------------------------------------------------------- usage errors

LABEL_KEYS = ", ".join(sorted(f.name for f in dataclasses.fields(LabelParams)))


def _usage_case(tmp_path: Path, case: str) -> tuple[list[object], str]:
    session = _copy(tmp_path, GA)
    params = tmp_path / "params.yaml"
    if case == "no-such-folder":
        return [tmp_path / "nope"], f"{tmp_path / 'nope'}: expected a session or campaign folder, " \
                                    "found no such folder"
    if case == "folder-without-sessions":
        (tmp_path / "empty").mkdir()
        return [tmp_path / "empty"], (f"{tmp_path / 'empty'}: expected a session folder (with "
                                      "session.yaml) or a campaign folder of sessions, found a "
                                      "folder with neither")
    if case == "session-without-manifest":
        (session / "session.yaml").unlink()
        return [session], (f"{session}: expected a session folder (with session.yaml) or a "
                           "campaign folder of sessions, found a folder with neither")
    if case == "jobs-zero":
        return [session, "--jobs", 0], "--jobs: expected an integer ≥ 1, found 0"
    if case == "jobs-negative":
        return [session, "--jobs", -3], "--jobs: expected an integer ≥ 1, found -3"
    if case == "min-samples-one":
        return [session, "--min-samples", 1], ("command line: label.min_samples: expected an "
                                                "integer ≥ 2, found 1")
    if case == "params-unknown-key":
        params.write_text("label:\n  min_samples: 1000\n  bogus: 3\n", encoding="utf-8")
        return [session, "--params", params], (f"{params}: label.bogus: expected one of "
                                               f"{LABEL_KEYS}, found an unknown key")
    if case == "params-unknown-nested-key":
        params.write_text("label:\n  static: {window: 3}\n", encoding="utf-8")
        return [session, "--params", params], (f"{params}: label.static.window: expected one of "
                                               "max_std_mps2, variance_factor, window_s, found an "
                                               "unknown key (did you mean window_s?)")
    if case == "params-wrong-type":
        params.write_text("label:\n  min_samples: many\n", encoding="utf-8")
        return [session, "--params", params], (f"{params}: label.min_samples: expected an "
                                               "integer, found 'many'")
    raise AssertionError(case)


@pytest.mark.parametrize("case", ["no-such-folder", "folder-without-sessions",
                                  "session-without-manifest", "jobs-zero", "jobs-negative",
                                  "min-samples-one", "params-unknown-key",
                                  "params-unknown-nested-key", "params-wrong-type"])
def test_usage_errors_exit_2_with_one_line(tmp_path, capsys, case):
    args, message = _usage_case(tmp_path, case)
    out = tmp_path / "out"
    assert _run(capsys, *args, "--out", out, "--quiet") == (2, f"ofbe-label: error: {message}\n")
    assert _files(out) == []


def test_missing_params_file_is_a_usage_error(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    params = tmp_path / "absent.yaml"
    rc, err = _run(capsys, session, "--params", params, "--out", tmp_path / "out", "--quiet")
    assert rc == 2
    assert err.startswith(f"ofbe-label: error: {params}: ") and err.count("\n") == 1
    assert "no such file" in err.lower()
    assert _files(tmp_path / "out") == []


def test_params_yaml_syntax_error_names_the_line(tmp_path, capsys):
    session = _copy(tmp_path, GA)
    params = tmp_path / "params.yaml"
    params.write_text("label:\n  min_samples: [1000\n  margin_s: 1.0\n", encoding="utf-8")
    rc, err = _run(capsys, session, "--params", params, "--out", tmp_path / "out", "--quiet")
    assert rc == 2
    assert err.startswith(f"ofbe-label: error: {params}:3: <document>: expected valid YAML, found ")
    assert _files(tmp_path / "out") == []


# --------------------------------------------------------------------------- garbled logs (fuzz)

FUZZ_TARGETS = [(GA, "rec-01/sparkfun-1.csv"), (ROT, "rec-01/sparkfun-2.csv"),
                (MP, "rec-03/sparkfun-1.csv")]

_MUTATION = st.one_of(
    st.tuples(st.just("flip"), st.lists(st.tuples(st.integers(0, 2**20), st.integers(0, 255)),
                                        min_size=1, max_size=20)),
    st.tuples(st.just("junk"), st.lists(st.tuples(st.integers(0, 2**20), st.binary(max_size=40)),
                                        min_size=1, max_size=20)),
    st.tuples(st.just("truncate"), st.integers(0, 2**20)),
    st.tuples(st.just("delete"), st.tuples(st.integers(0, 2**20), st.integers(1, 600))),
    st.tuples(st.just("duplicate"), st.tuples(st.integers(0, 2**20), st.integers(1, 600))),
)


def _mutate(data: bytes, mutations) -> bytes:
    for kind, arg in mutations:
        if kind == "flip" and data:
            buf = bytearray(data)
            for pos, value in arg:
                buf[pos % len(buf)] = value
            data = bytes(buf)
        elif kind == "junk":
            lines = data.split(b"\n")
            for pos, junk in arg:
                lines.insert(pos % (len(lines) + 1), junk)
            data = b"\n".join(lines)
        elif kind == "truncate":
            data = data[: arg % (len(data) + 1)]
        elif kind in ("delete", "duplicate"):
            lines = data.split(b"\n")
            at, count = arg[0] % len(lines), arg[1]
            if kind == "delete":
                del lines[at:at + count]
            else:
                lines[at:at] = lines[at:at + count]
            data = b"\n".join(lines)
    return data


@pytest.mark.slow
@settings(max_examples=30, deadline=None, derandomize=True)
@given(target=st.sampled_from(FUZZ_TARGETS), mutations=st.lists(_MUTATION, min_size=1, max_size=4))
def test_garbled_dut_logs_never_crash(tmp_path_factory, target, mutations):
    """Byte flips, junk lines, truncation, deleted and duplicated blocks in one DUT file:
    labelling returns finite labels or raises an OfbeError naming that file, nothing else."""
    name, rel = target
    session = _copy(tmp_path_factory.mktemp("fuzz"), name)
    path = session / rel
    path.write_bytes(_mutate(path.read_bytes(), mutations))
    try:
        labels = label_session(session, PARAMS)
    except OfbeError as exc:
        assert str(exc).startswith(f"{path}:")
        return
    for row in labels.rows:
        assert np.all(np.isfinite([row["bias_x"], row["bias_y"], row["bias_z"]]))
