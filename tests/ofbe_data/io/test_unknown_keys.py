"""Unknown keys are errors, never ignored (issue 36): in a manifest at every level, and in parameter
files, each with the closest known key or where the key belongs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.errors import ConfigError, ManifestError
from ofbe_data.io.device_options import BinOptions, CsvMapping
from ofbe_data.io.manifest import (
    DEVICE_KEYS,
    RECORDING_KEYS,
    SITE_KEYS,
    TOP_KEYS,
    DeviceSpec,
    RecordingSpec,
    SessionManifest,
    Site,
    device_keys,
    load_manifest,
    write_manifest,
)
from ofbe_data.io.pipeline_params import load_params
from ofbe_data.io.typedconfig import closest_key, key_paths, unknown_key_found
from ofbe_data.labelling.labels import LabelParams, label_params_from, read_label_section
from ofbe_data.simulator.config import load_config
from tests.helpers.paths import ROOT

MANIFEST = """\
format: ofbe-session/1
campaign: bench
session: pc-01
kind: gravity-aligned
site: {latitude_deg: 32.794, height_m: 35.0}
power_cycle: 1
devices:
  imu:
    model: BMI160
    role: dut
    format: csv
    columns: {t: time, ax: a_x, ay: a_y, az: a_z, temperature: temp}
    temperature_unit: F
recordings:
  - id: rec-01
    files: {imu: rec-01/imu.csv}
"""

TOP = "campaign, devices, format, gravity_mps2, kind, power_cycle, recordings, session, site"
CSV_ENTRY = ("acc_unit, columns, comment, delimiter, format, gyro_unit, header, lsb_per_g, model, range_g, "
             "reference_to_sensor, role, sample_rate_hz, skip_rows, sort_by_time, temperature_unit, "
             "time_unit, zero_counts")
LABEL_KEYS = ", ".join(sorted(f.name for f in dataclasses.fields(LabelParams)))


def _load(tmp_path: Path, text: str) -> Path:
    folder = tmp_path / "pc-01"
    folder.mkdir(exist_ok=True)
    (folder / "session.yaml").write_text(text, encoding="utf-8")
    return folder / "session.yaml"


def _message(tmp_path: Path, text: str) -> str:
    path = _load(tmp_path, text)
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    assert str(info.value).startswith(f"{path}:")
    return str(info.value).removeprefix(f"{path}:")


def test_the_manifest_loads_as_written(tmp_path: Path) -> None:
    assert load_manifest(_load(tmp_path, MANIFEST)).devices["imu"].csv.temperature_unit == "F"


def test_a_misspelt_key_is_refused_with_the_closest_key(tmp_path: Path) -> None:
    text = MANIFEST.replace("temperature_unit: F", "temprature_unit: F")
    assert _message(tmp_path, text) == (
        f"13: devices.imu.temprature_unit: expected one of {CSV_ENTRY}, found an unknown key "
        "(did you mean temperature_unit?)")


def test_a_labelling_parameter_in_a_manifest_says_where_it_belongs(tmp_path: Path) -> None:
    text = MANIFEST.replace("power_cycle: 1\n", "power_cycle: 1\nfit_model: full\n")
    assert _message(tmp_path, text) == (
        f"7: fit_model: expected one of {TOP}, found an unknown key (fit_model belongs in the label: "
        "section of params.yaml, as label.fit_model)")


def test_an_unknown_key_in_a_device_entry(tmp_path: Path) -> None:
    text = MANIFEST.replace("    role: dut\n", "    role: dut\n    operator: alice\n")
    assert _message(tmp_path, text) == (
        f"11: devices.imu.operator: expected one of {CSV_ENTRY}, found an unknown key")


def test_a_csv_option_on_another_format_names_the_formats_that_read_it(tmp_path: Path) -> None:
    csv = "    format: csv\n    columns: {t: time, ax: a_x, ay: a_y, az: a_z, temperature: temp}\n"
    text = MANIFEST.replace(csv + "    temperature_unit: F\n", "    format: ofbe-logger\n    acc_unit: g\n")
    assert _message(tmp_path, text) == (
        "12: devices.imu.acc_unit: expected one of format, model, reference_to_sensor, role, found an "
        "unknown key (acc_unit belongs at devices.<id>.acc_unit with format: csv or mscip-bin)")


@pytest.mark.parametrize(("old", "new", "message"), [
    ("height_m: 35.0", "height: 35.0",
     "5: site.height: expected one of gravity_mps2, height_m, latitude_deg, found an unknown key "
     "(did you mean height_m?)"),
    ("power_cycle: 1\n", "power_cycle: 1\nlatitude_deg: 32.8\n",
     f"7: latitude_deg: expected one of {TOP}, found an unknown key (latitude_deg belongs at "
     "site.latitude_deg)"),
    ("  - id: rec-01\n", "  - id: rec-01\n    notes: tripod moved\n",
     "16: recordings[0].notes: expected one of files, id, nominal, found an unknown key"),
    ("temperature: temp", "temprature: temp",
     "12: devices.imu.columns.temprature: expected a column key among t, ax, ay, az, temperature, gx, gy, "
     "gz, found str 'temprature' (did you mean temperature?)"),
    ("    role: dut\n", "    role: dut\n    noise_mg: 3.5\n",
     f"11: devices.imu.noise_mg: expected one of {CSV_ENTRY}, found an unknown key (noise_mg belongs in a "
     "simulator configuration, as dut_model.noise_mg or reference_model.noise_mg)"),
])
def test_unknown_keys_at_every_level(tmp_path: Path, old: str, new: str, message: str) -> None:
    assert old in MANIFEST
    assert _message(tmp_path, MANIFEST.replace(old, new)) == message


def test_a_misspelt_top_key_is_reported_before_the_key_it_hides(tmp_path: Path) -> None:
    text = MANIFEST.replace("campaign: bench", "campaing: bench")
    assert _message(tmp_path, text) == (
        f"2: campaing: expected one of {TOP}, found an unknown key (did you mean campaign?)")


def test_every_committed_manifest_loads() -> None:
    """The rule refuses nothing that the repository's own sessions hold."""
    root = ROOT
    paths = sorted(p for top in ("raw", "tests/data") for p in (root / top).rglob("session.yaml"))
    assert len(paths) >= 9
    for path in paths:
        load_manifest(path)


def test_known_keys_are_the_records_fields() -> None:
    def names(cls: type) -> set[str]:
        return {f.name for f in dataclasses.fields(cls)}

    assert TOP_KEYS == names(SessionManifest) - {"folder"} | {"format", "gravity_mps2"}
    assert SITE_KEYS == names(Site) and RECORDING_KEYS == names(RecordingSpec)
    assert DEVICE_KEYS == names(DeviceSpec) - {"id", "csv", "bin"}
    assert device_keys("csv") == DEVICE_KEYS | names(CsvMapping)
    assert device_keys("mscip-bin") == DEVICE_KEYS | names(BinOptions)
    assert device_keys("ofbe-logger") == device_keys("mscip-csv") == DEVICE_KEYS


def test_every_option_the_writer_writes_reads_back(tmp_path: Path) -> None:
    """What :func:`write_manifest` writes is never refused: every options field set off its default."""
    columns: dict[str, str | int] = {k: i for i, k in enumerate(("t", "ax", "ay", "az", "temperature", "gx",
                                                                 "gy", "gz"))}
    csv = CsvMapping(columns, time_unit="ms", acc_unit="counts", lsb_per_g=(256.0, 256.0, 250.0),
                     skip_rows=2, delimiter=";", header=False, comment="#", sample_rate_hz=100.0,
                     zero_counts=(1.0, 2.0, 3.0), temperature_unit="K", range_g=16.0, gyro_unit="deg/s",
                     sort_by_time=True)
    assert {f.name for f in dataclasses.fields(CsvMapping)} == set(csv.to_dict())
    devices = {"imu": DeviceSpec("imu", "BMI160", "dut", "csv", np.eye(3), csv=csv),
               "ms": DeviceSpec("ms", "MS-IMU3025", "dut", "mscip-bin", bin=BinOptions(200.0, "mg"))}
    manifest = SessionManifest(tmp_path, "bench", "pc-01", "multi-position", Site(gravity_mps2=9.79), 1,
                               devices, (RecordingSpec("rec-01", {"imu": "a.csv", "ms": "b.bin"},
                                                       {"roll_deg": 1.0}),))
    again = load_manifest(write_manifest(manifest, tmp_path / "session.yaml"))
    assert again.to_dict() == manifest.to_dict()


def test_a_misspelt_parameter_is_refused_with_the_closest_key(tmp_path: Path) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("label:\n  fit_modle: full\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        label_params_from(read_label_section(params), params)
    assert str(info.value) == (f"{params}: label.fit_modle: expected one of {LABEL_KEYS}, found an unknown "
                               "key (did you mean fit_model?)")


@pytest.mark.parametrize(("data", "key", "found"), [
    ({"temperature_unit": "F"}, "label.temperature_unit",
     "an unknown key (temperature_unit belongs in session.yaml, as devices.<id>.temperature_unit with "
     "format: csv)"),
    ({"window_s": 3.0}, "label.window_s",
     "an unknown key (window_s belongs at label.static.window_s or label.sync.window_s or "
     "label.poses.window_s)"),
    ({"static": {"window": 3.0}}, "label.static.window", "an unknown key (did you mean window_s?)"),
    ({"bogus": 3}, "label.bogus", "an unknown key"),
])
def test_parameters_say_where_a_key_belongs(data: dict[str, object], key: str, found: str) -> None:
    with pytest.raises(ConfigError) as info:
        label_params_from(data, "params.yaml")
    assert (info.value.key, info.value.found) == (key, found)


def test_simulator_configuration_keys_get_the_same_rule() -> None:
    with pytest.raises(ConfigError) as info:
        load_config("rotated", {"dut_model": {"noise": 1.0}})
    assert (info.value.key, info.value.found) == ("dut_model.noise",
                                                  "an unknown key (did you mean noise_mg?)")
    with pytest.raises(ConfigError) as info:
        load_config("rotated", {"fit_model": "full"})
    assert info.value.found == ("an unknown key (fit_model belongs in the label: section of params.yaml, as "
                                "label.fit_model; or did you mean dut_model?)")


def test_a_misspelt_profile_names_the_closest(tmp_path: Path) -> None:
    (tmp_path / "pipelines" / "profiles").mkdir(parents=True)
    (tmp_path / "pipelines" / "profiles" / "tiny.yaml").write_text("label: {}\n", encoding="utf-8")
    params = tmp_path / "params.yaml"
    params.write_text("profile: tinny\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_params(params)
    assert str(info.value) == (f"{params}: profile: expected paper or one of tiny, found 'tinny' "
                               "(did you mean tiny?)")


def test_hint_helpers() -> None:
    assert closest_key("temprature_unit", ["time_unit", "temperature_unit"]) == "temperature_unit"
    assert closest_key("operator", ["model", "role"]) is None
    assert key_paths(LabelParams, "label")["fit_model"] == ("label.fit_model",)
    assert unknown_key_found("x", ["y"]) == "an unknown key"
    assert unknown_key_found("x", ["y"], ("a.x", "b.x", "c.x", "d.x")) == (
        "an unknown key (x belongs at a.x or b.x or c.x (and 1 more))")
