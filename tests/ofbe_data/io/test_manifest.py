"""Manifest validation: each rule with its exact error, and the write → read round trip."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.errors import ManifestError
from ofbe_data.io.gravity import local_gravity
from ofbe_data.io.manifest import load_manifest, write_manifest

VALID = """\
format: ofbe-session/1
campaign: rotated-2025-03
session: rot-pc07
kind: rotated
site: {latitude_deg: 32.794, height_m: 35.0}
power_cycle: 7
devices:
  sparkfun-1:
    model: ADXL345
    role: dut
    format: ofbe-logger
    reference_to_sensor: [[1,0,0],[0,1,0],[0,0,1]]
  memsense:
    model: MS-IMU3025
    role: reference
    format: mscip-csv
recordings:
  - id: rec-01
    nominal: {roll_deg: 0.0, pitch_deg: 30.0}
    files: {sparkfun-1: rec-01/sparkfun-1.csv, memsense: rec-01/memsense.csv}
  - id: rec-02
    files: {sparkfun-1: rec-02/sparkfun-1.csv, memsense: rec-02/memsense.csv}
"""


def _manifest(tmp_path: Path, text: str) -> Path:
    folder = tmp_path / "rot-pc07"
    folder.mkdir(exist_ok=True)
    path = folder / "session.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _error(tmp_path: Path, text: str) -> ManifestError:
    with pytest.raises(ManifestError) as info:
        load_manifest(_manifest(tmp_path, text))
    return info.value


def test_valid_manifest_is_typed(tmp_path):
    m = load_manifest(_manifest(tmp_path, VALID).parent)
    assert (m.campaign, m.session, m.kind, m.power_cycle) == ("rotated-2025-03", "rot-pc07",
                                                              "rotated", 7)
    assert [d.id for d in m.duts] == ["sparkfun-1"]
    assert m.reference is not None and m.reference.id == "memsense"
    assert m.g_local == pytest.approx(local_gravity(32.794, 35.0))
    assert m.recordings[0].nominal == {"roll_deg": 0.0, "pitch_deg": 30.0}
    assert m.file_path(m.recordings[1], "memsense") == m.folder / "rec-02/memsense.csv"
    np.testing.assert_array_equal(m.devices["sparkfun-1"].reference_to_sensor, np.eye(3))


def test_round_trip_write_read(tmp_path):
    m = load_manifest(_manifest(tmp_path, VALID))
    out = tmp_path / "copy" / "session.yaml"
    out.parent.mkdir()
    write_manifest(m, out)
    again = load_manifest(out)
    assert again.to_dict() == m.to_dict()
    assert again.folder == out.parent


def test_gravity_override_top_level_or_in_site(tmp_path):
    top = VALID.replace("site: {latitude_deg: 32.794, height_m: 35.0}", "gravity_mps2: 9.7955")
    assert load_manifest(_manifest(tmp_path, top)).g_local == 9.7955
    inside = VALID.replace("site: {latitude_deg: 32.794, height_m: 35.0}",
                           "site: {gravity_mps2: 9.7961}")
    assert load_manifest(_manifest(tmp_path, inside)).g_local == 9.7961


def test_unknown_kind(tmp_path):
    err = _error(tmp_path, VALID.replace("kind: rotated", "kind: spinning"))
    assert str(err).endswith(":4: kind: expected one of gravity-aligned, rotated, "
                             "multi-position, found str 'spinning'")
    assert err.field == "kind" and err.line == 4


def test_file_for_undeclared_device(tmp_path):
    text = VALID.replace("files: {sparkfun-1: rec-02/sparkfun-1.csv,",
                         "files: {sparkfun-9: rec-02/sparkfun-1.csv,")
    err = _error(tmp_path, text)
    assert err.field == "recordings[1].files.sparkfun-9"
    assert err.expected == "a device declared under devices (sparkfun-1, memsense)"
    assert err.found == "unknown device 'sparkfun-9'"
    assert err.line == 22


def test_declared_device_without_file(tmp_path):
    text = VALID.replace("files: {sparkfun-1: rec-02/sparkfun-1.csv, memsense: "
                         "rec-02/memsense.csv}", "files: {sparkfun-1: rec-02/sparkfun-1.csv}")
    err = _error(tmp_path, text)
    assert (err.field, err.expected, err.found) == (
        "recordings[1].files", "a file for declared device 'memsense'", "no entry for it")


def test_missing_device_field(tmp_path):
    err = _error(tmp_path, VALID.replace("    role: reference\n", ""))
    assert err.field == "devices.memsense.role" and err.found == "it missing"


@pytest.mark.parametrize("path", ["../rot-pc06/rec-01/memsense.csv", "rec-01/../../x.csv",
                                  "/etc/passwd"])
def test_path_escaping_session_folder(tmp_path, path):
    err = _error(tmp_path, VALID.replace("memsense: rec-01/memsense.csv",
                                         f"memsense: {path}"))
    assert err.field == "recordings[0].files.memsense"
    assert "session folder" in err.expected
    assert repr(path) in err.found


def test_symlink_escaping_session_folder(tmp_path):
    path = _manifest(tmp_path, VALID)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    os.symlink(outside, path.parent / "rec-01")
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    assert info.value.field == "recordings[0].files.sparkfun-1"
    assert "resolves (through a link)" in info.value.found


def test_duplicate_recording_ids(tmp_path):
    err = _error(tmp_path, VALID.replace("id: rec-02", "id: rec-01"))
    assert err.field == "recordings[1].id"
    assert err.found == "duplicate id 'rec-01' (also recordings[0].id)"
    assert err.line == 21


def test_duplicate_device_ids_are_not_silently_merged(tmp_path):
    text = VALID.replace("  memsense:\n", "  sparkfun-1:\n")
    err = _error(tmp_path, text)
    assert str(err).endswith(":13: devices.sparkfun-1: expected unique keys, found a duplicate "
                             "of the key on line 8")


def test_same_file_twice(tmp_path):
    err = _error(tmp_path, VALID.replace("memsense: rec-02/memsense.csv",
                                         "memsense: rec-02/./sparkfun-1.csv"))
    assert err.field == "recordings[1].files.memsense"
    assert err.found == "'rec-02/./sparkfun-1.csv', also named for device 'sparkfun-1'"
    assert "each reads its own columns (format csv, different ax, ay, az)" in err.expected
    err = _error(tmp_path, VALID.replace("memsense: rec-02/memsense.csv", "memsense: rec-01/memsense.csv"))
    assert err.field == "recordings[1].files.memsense"
    assert "also named at recordings[0].files.memsense" in err.found and "one recording only" in err.expected


def test_rotated_needs_exactly_one_reference(tmp_path):
    err = _error(tmp_path, VALID.replace("role: reference", "role: dut"))
    assert err.field == "devices"
    assert err.found == "0 (none)"


def test_gravity_aligned_must_not_have_reference(tmp_path):
    err = _error(tmp_path, VALID.replace("kind: rotated", "kind: gravity-aligned"))
    assert err.field == "devices.memsense.role"


def test_reference_to_sensor_must_be_rotation(tmp_path):
    err = _error(tmp_path, VALID.replace("[[1,0,0],[0,1,0],[0,0,1]]", "[[1,0,0],[0,1,0],[0,0,-1]]"))
    assert err.field == "devices.sparkfun-1.reference_to_sensor"
    assert err.expected == "a rotation (orthonormal rows, determinant +1)"


def test_bad_format_version_and_yaml_syntax(tmp_path):
    err = _error(tmp_path, VALID.replace("ofbe-session/1", "ofbe-session/9"))
    assert (err.field, err.line) == ("format", 1)
    err = _error(tmp_path, VALID.replace("power_cycle: 7", "power_cycle: [7"))
    assert err.field == "<document>" and err.expected == "valid YAML" and err.line is not None


def test_generic_csv_device_needs_mapping(tmp_path):
    text = VALID.replace("format: ofbe-logger", "format: csv\n    columns: {t: time, ax: a, ay: b}")
    err = _error(tmp_path, text)
    assert err.field == "devices.sparkfun-1.columns.az" and err.found == "it missing"


def test_missing_manifest_file(tmp_path):
    with pytest.raises(ManifestError, match="no such file"):
        load_manifest(tmp_path / "nothing")
