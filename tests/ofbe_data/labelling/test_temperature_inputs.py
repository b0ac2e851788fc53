"""Temperature columns no sensor reads, temperature cells without a value, and temperature models
the poses cannot give (issue 36): each shape is a small file written here, with its exact message
or result.

- **Range**: a device temperature lies within −40…125 °C (MEMS datasheets). Values beyond it in the
  declared unit are refused, naming the file, the line, the value and the unit they look like
  (kelvin, °F); declared, that unit is converted to °C. Values that fit no unit (1000 °C), or a
  few glitches among good values, are refused too, saying so.
- **Cells without a value** (empty, ``NaN``, ``NA``…) leave their sample without temperature, never
  the line skipped: an all-NaN column is a file without temperature (a warning naming it), a pose
  whose samples have none leaves the temperature models out, never the pose or the recording.
- **Temperature models** that the poses cannot give (a temperature missing, a span under 5 °C,
  a constant one) say so: skipped with that reason by ``auto``, refused with it when forced.
- **``ofbe-session init``** says kelvin / °F in its decisions, or leaves a column no unit settles
  unmapped with a warning.

Multi-position sessions are one continuous file of 24 poses (3 s still, 1 s turns, 50 Hz, g with
5 decimals, 1 mg of noise, 20–30 mg offsets, 1 % scale errors) read as a generic csv.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.label import main as label_main
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.detection import sniff_text
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.recording import TEMPERATURE, ImplausibleTemperatureError, Recording
from ofbe_data.labelling.labels import LabelParams, label_session
from ofbe_data.labelling.multiposition._fit import fit_poses
from ofbe_data.labelling.multiposition._ladder import choose_fit

G0 = 9.80665
MG = G0 / 1000.0
RATE = 50.0
REST = 150  # samples still per pose (3 s)
TURN = 50  # samples turning between poses (1 s)
K = 24

MANIFEST = """format: ofbe-session/1
campaign: temps
session: {session}
kind: multi-position
site: {{gravity_mps2: {g}}}
power_cycle: 1
devices:
  dut:
    model: X
    role: dut
    format: csv
    columns: {{t: t, ax: ax, ay: ay, az: az, temperature: temp}}
    acc_unit: g
{extra}recordings:
  - id: rec-01
    files: {{dut: rec-01/log.csv}}
"""


# --------------------------------------------------------------------------- files


def _directions() -> np.ndarray:
    """(K, 3) unit vectors spread over the sphere (Fibonacci)."""
    i = np.arange(K) + 0.5
    z = 1.0 - 2.0 * i / K
    phi = np.pi * (1.0 + 5.0**0.5) * i
    return np.column_stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])


def pose_file(cell: Callable[[int, int], str], seed: int = 5) -> str:
    """A continuous 24-pose recording as csv text ``t,ax,ay,az,temp``; ``cell(pose, i)`` writes the
    temperature cell of sample ``i`` of a pose (still samples first, then the turn to the next)."""
    rng = np.random.default_rng(seed)
    u = _directions()
    force, cells = [], []
    for p in range(K):
        force.append(np.tile(G0 * u[p], (REST, 1)))
        cells += [cell(p, i) for i in range(REST)]
        if p + 1 < K:
            s = np.linspace(0.0, 1.0, TURN + 2)[1:-1, None]
            v = (1 - s) * u[p] + s * u[p + 1] + 0.3 * np.sin(np.pi * s) * rng.normal(size=3)
            v /= np.linalg.norm(v, axis=1, keepdims=True)
            force.append(G0 * v + 2.0 * np.sin(np.pi * s) * rng.normal(size=(TURN, 3)))
            cells += [cell(p, REST + i) for i in range(TURN)]
    f = np.vstack(force)
    g = (f @ np.diag([1.01, 0.99, 1.005]).T + np.array([20.0, -15.0, 30.0]) * MG
         + rng.normal(scale=MG, size=f.shape)) / G0
    t = np.arange(f.shape[0]) / RATE
    return "t,ax,ay,az,temp\n" + "".join(f"{ti:.2f},{x:.5f},{y:.5f},{z:.5f},{c}\n"
                                         for ti, (x, y, z), c in zip(t, g, cells, strict=True))


def pose_temperatures(seed: int = 3) -> np.ndarray:
    """(K,) °C, 20–35 °C in an order unrelated to the poses' directions."""
    return 20.0 + 15.0 * np.random.default_rng(seed).permutation(K) / (K - 1)


def session(folder: Path, text: str, extra: str = "") -> Path:
    """A multi-position session of one generic csv file ``rec-01/log.csv`` holding ``text``;
    ``extra``: more keys of the device entry (indented lines)."""
    (folder / "rec-01").mkdir(parents=True)
    (folder / "rec-01" / "log.csv").write_text(text, encoding="utf-8")
    (folder / "session.yaml").write_text(MANIFEST.format(session=folder.name, g=G0, extra=extra),
                                         encoding="utf-8")
    return folder


def read(folder: Path) -> Recording:
    m = load_manifest(folder)
    return read_device_file(m.file_path(m.recordings[0], "dut"), m.devices["dut"])


def small_file(tmp_path: Path, cells: list[str], extra: str = "") -> Path:
    """A session whose file holds one still sample per temperature cell (2 decimals of t)."""
    rows = "".join(f"{i / RATE:.2f},0.01,0.02,0.99,{c}\n" for i, c in enumerate(cells))
    return session(tmp_path / "s", "t,ax,ay,az,temp\n" + rows, extra)


def label_cli(capsys, tmp_path: Path, folder: Path, *args: str) -> tuple[int, str]:
    rc = label_main([str(folder), "--out", str(tmp_path / "out"), "--quiet", *args])
    return rc, capsys.readouterr().err


# --------------------------------------------------------------------------- range


def test_a_kelvin_column_read_as_celsius_is_refused_naming_kelvin(tmp_path: Path, capsys) -> None:
    """Issue 36: kelvin read as °C gave 288 °C. The first line beyond 125 °C is named, with the
    value, and the unit the column's values fit; ofbe-label stops on the session (exit 1)."""
    folder = small_file(tmp_path, ["288.15"] * 5 + ["291.05"] * 5)
    path = folder / "rec-01" / "log.csv"
    message = (f"{path}:2: expected a device temperature from -40 to 125 °C in column 'temp' "
               "(temperature_unit: C, degrees Celsius), found 288.15 (the values, 288.15 to 291.05, look "
               "like kelvin (15.0 to 17.9 °C): set temperature_unit: K)")
    with pytest.raises(ImplausibleTemperatureError) as err:
        read(folder)
    assert str(err.value) == message and isinstance(err.value, RawFormatError) and err.value.line == 2
    assert label_cli(capsys, tmp_path, folder) == (1, f"ofbe-label: error: {message}\n")


def test_a_fahrenheit_column_beyond_celsius_is_refused_naming_fahrenheit(tmp_path: Path) -> None:
    """A chamber at 55–60 °C logged in °F: 131–140 read as °C are beyond the range, as kelvin far
    below it; the line of the first value beyond is named (line 4: two good values before)."""
    folder = small_file(tmp_path, ["120.0", "124.5", "131.0", "140.0"] + ["135.5"] * 6)
    with pytest.raises(ImplausibleTemperatureError, match=r"log\.csv:4: expected a device temperature "
                       r"from -40 to 125 °C in column 'temp' \(temperature_unit: C, degrees Celsius\), found "
                       r"131 \(the values, 120 to 140, look like degrees Fahrenheit \(48\.9 to 60\.0 °C\): "
                       r"set temperature_unit: F\)$"):
        read(folder)


def test_a_1000_degree_column_fits_no_unit_and_says_so(tmp_path: Path) -> None:
    folder = small_file(tmp_path, ["1000"] * 10)
    with pytest.raises(ImplausibleTemperatureError, match=r"log\.csv:2: expected .* found 1000 \(the "
                       r"values, 1000, are no device temperature in C, K or F \(a scaled or raw value\?\): "
                       r"leave columns\.temperature out to read the file without temperature\)$"):
        read(folder)


def test_a_glitch_among_good_temperatures_is_refused_naming_its_line(tmp_path: Path) -> None:
    folder = small_file(tmp_path, ["25.0"] * 6 + ["-273.0"] + ["25.5"] * 3)
    with pytest.raises(ImplausibleTemperatureError, match=r"log\.csv:8: expected .* found -273 \(1 of 10 "
                       r"values is outside the range, the others 25 to 25\.5: leave columns\.temperature "
                       r"out"):
        read(folder)


def test_two_units_that_fit_are_both_named(tmp_path: Path) -> None:
    folder = small_file(tmp_path, ["245.0"] * 10)
    with pytest.raises(ImplausibleTemperatureError, match=r"look like kelvin \(-28\.1 °C\) or degrees "
                       r"Fahrenheit \(118\.3 °C\): set temperature_unit: K or F\)$"):
        read(folder)


@pytest.mark.parametrize("unit, cells, celsius", [
    ("K", ["288.15", "291.15", "233.15", "398.15"], [15.0, 18.0, -40.0, 125.0]),
    ("F", ["131", "140", "-40", "257"], [55.0, 60.0, -40.0, 125.0]),
    ("C", ["-40", "125", "31.2", "0"], [-40.0, 125.0, 31.2, 0.0]),
])
def test_a_declared_unit_is_converted_to_celsius_up_to_the_range_ends(tmp_path: Path, unit: str,
                                                                      cells: list[str],
                                                                      celsius: list[float]) -> None:
    rec = read(small_file(tmp_path, cells * 3, f"    temperature_unit: {unit}\n"))
    np.testing.assert_allclose(rec.extra[TEMPERATURE], celsius * 3, atol=1e-9)


def test_celsius_declared_as_kelvin_is_refused_naming_celsius(tmp_path: Path) -> None:
    folder = small_file(tmp_path, ["24.5"] * 10, "    temperature_unit: K\n")
    with pytest.raises(ImplausibleTemperatureError, match=r"log\.csv:2: expected a device temperature from "
                       r"-40 to 125 °C in column 'temp' \(temperature_unit: K, kelvin\), found 24\.5 \(the "
                       r"values, 24\.5, look like degrees Celsius \(24\.5 °C\) or degrees Fahrenheit "
                       r"\(-4\.2 °C\): set temperature_unit: C or F\)$"):
        read(folder)


# --------------------------------------------------------------------------- cells without a value


def test_cells_without_a_value_leave_their_sample_without_temperature(tmp_path: Path) -> None:
    """Empty, NaN, NA, null and n/a cells are samples without temperature; text that is no number
    and no missing marker still skips its line, as before."""
    cells = ["25.0", "", "NaN", "26.0", " NA ", "null", "n/a", "abc", "27.0", "nan"]
    rec = read(small_file(tmp_path, cells))
    assert rec.n == 9
    np.testing.assert_array_equal(rec.line, [2, 3, 4, 5, 6, 7, 8, 10, 11])
    np.testing.assert_array_equal(rec.extra[TEMPERATURE],
                                  [25.0, np.nan, np.nan, 26.0, np.nan, np.nan, np.nan, 27.0, np.nan])
    assert [(s.line, s.kind, s.detail) for s in rec.diagnostics.skipped] == [
        (9, "non-numeric", "field 'c4' is not a number: 'abc'")]
    assert rec.header["temperature_note"] == (
        "6 of 9 samples have no temperature in column 'temp' (empty or NaN cells, the first at line 3): "
        "an interval's temperature is the mean over its samples that have one")


def test_an_all_nan_temperature_column_is_a_file_without_temperature(tmp_path: Path) -> None:
    """Issue 36: every acceleration value is valid, yet an all-NaN temperature column made the file
    "no valid data line". Now every sample is kept, the labels have no temperature, and a warning
    names the file."""
    folder = session(tmp_path / "nan-column", pose_file(lambda p, i: "NaN"))
    rec = read(folder)
    assert rec.n == K * REST + (K - 1) * TURN and TEMPERATURE not in rec.extra
    labels = label_session(folder)
    assert labels.rejections == [] and len(labels.rows) == K
    assert all(r["temperature_c"] is None for r in labels.rows)
    assert ("rec-01/dut: log.csv: the temperature column 'temp' holds no value (every cell empty or NaN): "
            "read without temperature") in labels.warnings
    assert "temperature" not in labels.rows[0]["fit_model_reason"]


def test_one_pose_without_temperature_leaves_the_temperature_models_out_not_the_pose(tmp_path: Path) -> None:
    """Issue 36: one pose's NaN temperature rejected a 24-pose recording as garbled. Now all 24
    poses are labelled; the pose without temperature has none, the others their mean (over
    the samples that have one: a few empty cells inside a pose do not matter), and the ladder
    says why it tried no temperature slope (it does on the same poses with every temperature)."""
    temps = pose_temperatures()

    def cell(p: int, i: int) -> str:
        if p == 7:
            return "NaN"
        return "" if i % 10 == 3 else f"{temps[p]:.2f}"

    labels = label_session(session(tmp_path / "one-pose", pose_file(cell)))
    assert labels.rejections == [] and len(labels.rows) == K
    got = [r["temperature_c"] for r in labels.rows]
    assert got[7] is None
    np.testing.assert_allclose([x for k, x in enumerate(got) if k != 7], np.delete(np.round(temps, 2), 7),
                               atol=1e-9)
    reason = labels.rows[0]["fit_model_reason"]
    assert ("no temperature slope: 1 of 24 poses has no temperature (every temperature cell of its samples "
            "empty or NaN); a +temperature model needs one for every pose") in reason
    # pose 7's 200 samples (still and turn) and one in ten of the others' 4550
    assert labels.warnings == ["rec-01/dut: log.csv: 655 of 4750 samples have no temperature in column "
                               "'temp' (empty or NaN cells, the first at line 5): an interval's temperature "
                               "is the mean over its samples that have one"]
    every = label_session(session(tmp_path / "every-pose", pose_file(lambda p, i: f"{temps[p]:.2f}")))
    assert "(temperature span 15.0 °C)" in every.rows[0]["fit_model_reason"]


# --------------------------------------------------------------------------- temperature models


def test_a_forced_temperature_model_on_a_constant_temperature_is_refused_for_it(tmp_path: Path,
                                                                                capsys) -> None:
    """Issue 36: blamed on "poses do not span three dimensions" before. Refused as every forced
    model the poses cannot give: each pose a multi-position-undetermined rejection, exit 1."""
    folder = session(tmp_path / "constant", pose_file(lambda p, i: "25.00"))
    params = tmp_path / "params.yaml"
    params.write_text("label:\n  fit_model: offset+temperature\n", encoding="utf-8")
    rc, err = label_cli(capsys, tmp_path, folder, "--params", str(params))
    assert (rc, err) == (1, "ofbe-label: error: no recording was labelled (24 multi-position-undetermined; "
                            f"see the <session>.rejected.json files in {tmp_path / 'out'})\n")
    doc = json.loads((tmp_path / "out" / "temps" / "constant.rejected.json").read_text(encoding="utf-8"))
    details = [r["detail"] for r in doc["rejected"]]
    assert len(details) == K and all(
        "offset+temperature: temperature spans 0.0 °C across the poses (25.0 °C); a +temperature model "
        "needs 5 °C at least" in d for d in details)
    assert not any("span three dimensions" in d for d in details)
    auto = label_session(folder)
    assert "no temperature slope: the poses span 0.0 °C, 5 needed" in auto.rows[0]["fit_model_reason"]


def test_a_forced_temperature_model_with_a_pose_without_temperature_is_refused_for_it(tmp_path: Path) -> None:
    temps = pose_temperatures()
    text = pose_file(lambda p, i: "" if p == 11 else f"{temps[p]:.2f}")
    forced = LabelParams(fit_model="scale-offset+temperature")
    labels = label_session(session(tmp_path / "missing", text), forced)
    assert labels.rows == [] and len(labels.rejections) == K
    assert ("scale-offset+temperature: 1 of 24 poses has no temperature (every temperature cell of its "
            "samples empty or NaN); a +temperature model needs one for every pose"
            ) in labels.rejections[0].detail


def test_the_ladder_s_reasons_for_no_temperature_model() -> None:
    """Straight on pose means: forced and too narrow a span, no temperature at all, a constant one
    (fit_poses itself: the slope's reason, not the geometry's)."""
    means = G0 * _directions() + np.array([0.2, -0.1, 0.3])
    narrow = 25.0 + np.linspace(0.0, 3.0, K)
    forced = choose_fit(means, G0, "offset+temperature", temperatures=narrow)
    assert not forced.fit.determined
    assert forced.reason == ("offset+temperature: temperature spans 3.0 °C across the poses (25.0 to "
                             "28.0 °C); a +temperature model needs 5 °C at least")
    none = choose_fit(means, G0, "full+temperature", temperatures=None)
    assert none.reason == ("full+temperature: no pose has a temperature (no temperature column mapped, or "
                           "every cell of it empty or NaN); a +temperature model needs one for every pose")
    constant = fit_poses(means, G0, "offset+temperature", temperatures=np.full(K, 31.2))
    assert not constant.determined and constant.reason == (
        "temperature spans 0.0 °C across the poses (31.2 °C); a +temperature model needs poses at different "
        "temperatures")
    wide = choose_fit(means, G0, "offset+temperature", temperatures=pose_temperatures())
    assert wide.fit.determined and wide.reason.startswith("offset+temperature: forced by label.fit_model")


# --------------------------------------------------------------------------- ofbe-session init


def _init_file(tmp_path: Path, name: str, temps: np.ndarray) -> Path:
    rng = np.random.default_rng(2)
    n = temps.size
    g = np.array([0.01, 0.02, 1.0]) + rng.normal(0.0, 0.002, (n, 3))
    rows = "".join(f"{i / 100:.2f},{x:.5f},{y:.5f},{z:.5f},{c:.2f}\n"
                   for i, ((x, y, z), c) in enumerate(zip(g, temps, strict=True)))
    path = tmp_path / f"{name}.csv"
    path.write_text("t,ax_g,ay_g,az_g,temp\n" + rows, encoding="utf-8")
    return path


def test_init_says_kelvin_from_the_values_and_reads_the_file_back(tmp_path: Path) -> None:
    det = sniff_text(_init_file(tmp_path, "kelvin", np.linspace(295.0, 297.5, 500)))
    assert det.mapping is not None and det.mapping.temperature_unit == "K"
    assert ("temperature_unit: K (values 295 to 297.5 are beyond a device's -40 to 125 °C as °C; as kelvin "
            "they are 21.9 to 24.4 °C)") in det.lines()
    assert det.warnings == []


def test_init_leaves_a_column_no_unit_settles_unmapped_with_a_warning(tmp_path: Path) -> None:
    det = sniff_text(_init_file(tmp_path, "thousand", np.full(500, 1000.0)))
    assert det.mapping is not None and "temperature" not in det.mapping.columns
    why = ("the values, 1000, are no device temperature in C, K or F (a scaled or raw value?): leave "
           "columns.temperature out to read the file without temperature")
    assert f"temperature: not mapped ({why}: not mapped)" in det.lines()
    assert det.warnings == [f"temperature column 'temp' not mapped: {why}"]


def test_init_flags_room_fahrenheit_that_reads_as_hot_celsius(tmp_path: Path) -> None:
    """68–77 °F is a possible 20–25 °C and a possible (hot) 68–77 °C: kept as °C, flagged."""
    det = sniff_text(_init_file(tmp_path, "fahrenheit", np.linspace(68.0, 77.0, 500)))
    assert det.mapping is not None and det.mapping.temperature_unit == "C"
    assert det.warnings == ["temperature column 'temp' reads 72.5 °C (median), hot for a device at rest; as "
                            "degrees Fahrenheit it is 22.5 °C: if so, set temperature_unit: F"]


def test_the_reference_formats_temperature_gets_the_same_range(tmp_path: Path) -> None:
    """The Memsense csv export states °C; a kelvin-looking column in it is refused the same way."""
    from ofbe_data.io.formats.mscip_csv import read_mscip_csv, write_mscip_csv

    n = 50
    t = np.arange(n) / 100.0
    acc = np.tile([0.0, 0.0, 1.0], (n, 1))
    path = tmp_path / "ref.csv"
    write_mscip_csv(path, t, acc, np.zeros((n, 3)), np.full(n, 298.15), serial="MS-1", rate_hz=100.0,
                    start_utc="2025-03-14T09:00:00Z")
    with pytest.raises(ImplausibleTemperatureError) as err:
        read_mscip_csv(path)
    assert str(err.value) == (f"{path}:7: expected a device temperature from -40 to 125 °C in column "
                              "'Temperature (C)' (degrees Celsius), found 298.2 (the values, 298.2, look "
                              "like kelvin (25.1 °C): this format writes degrees Celsius: is the file "
                              "damaged, or of another format?)")
    write_mscip_csv(path, t, acc, np.zeros((n, 3)), np.full(n, 25.0), serial="MS-1", rate_hz=100.0,
                    start_utc="2025-03-14T09:00:00Z")
    assert np.all(read_mscip_csv(path).extra[TEMPERATURE] == 25.0)
