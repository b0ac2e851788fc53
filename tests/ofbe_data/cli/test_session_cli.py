"""``ofbe-session init`` and ``check`` on the command line: the manifest written from the files
alone (with its evidence as comments), the stops that name a flag, and the round trip init → check
on a simulated gravity-aligned session in each odd layout of test_detect.py, which must label
without modifying the raw folder.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from ofbe_data.cli.session import main
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.mscip_bin import write_mscip_bin
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest
from tests.helpers.paths import ROOT
from tests.ofbe_data.io.test_detect import LAYOUTS, quoted_units, sample_index, simulate

EXAMPLES = ROOT / "raw" / "examples"


def _session(tmp_path: Path, writer, files: int = 2, name: str = "pc 07") -> Path:
    """A session folder ``my camp!/<name>`` holding ``files`` recordings written by ``writer``."""
    folder = tmp_path / "my camp!" / name
    folder.mkdir(parents=True)
    for k in range(files):
        (folder / f"rec {k + 1:02d}.csv").write_bytes(writer(*simulate(seed=k)))
    return folder


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Bytes and modification times of everything under (and including) a folder."""
    out = {".": (b"", folder.stat().st_mtime_ns)}
    for p in sorted(folder.rglob("*")):
        content = p.read_bytes() if p.is_file() else b""
        out[p.relative_to(folder).as_posix()] = (content, p.stat().st_mtime_ns)
    return out


def _one_error(err: str) -> str:
    lines = [line for line in err.splitlines() if "warning" not in line]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.slow
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_init_then_check_labels_every_layout(tmp_path: Path, layout: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    writer, expected, flags = LAYOUTS[layout]
    folder = _session(tmp_path, writer)
    assert main(["init", str(folder), *flags]) == 0
    m = load_manifest(folder)
    entry = m.devices["dut"].to_dict()
    defaults = {"header": True, "delimiter": ",", "skip_rows": 0}
    assert {k: entry.get(k, defaults.get(k)) for k in expected} == expected
    for rec in m.recordings:  # the manifest reads every file
        assert read_device_file(m.file_path(rec, "dut"), m.devices["dut"]).n == 10_000
    before = _snapshot(folder)
    capsys.readouterr()
    assert main(["check", str(folder)]) == 0, capsys.readouterr().out
    out = capsys.readouterr().out
    assert "would label 2 of 2" in out
    assert _snapshot(folder) == before  # raw/ untouched: same bytes, same times


def test_init_writes_ids_evidence_and_the_gravity_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    folder = _session(tmp_path, quoted_units)
    assert main(["init", str(folder)]) == 0
    captured = capsys.readouterr()
    assert "acc_unit: g (the column names say so; ‖mean‖ = 1.0" in captured.out
    assert "wrote " in captured.out and "next: ofbe-session check" in captured.out
    assert "ofbe-session: warning: g_local is standard gravity 9.80665 m/s²" in captured.err
    text = (folder / "session.yaml").read_text(encoding="utf-8")
    assert "    acc_unit: g  # the column names say so; ‖mean‖ = 1.0" in text
    assert "    time_unit: s  # the column name 'Time (s)' says so" in text
    assert "campaign: my-camp  # the parent folder 'my camp!'" in text
    data = yaml.safe_load(text)
    assert (data["campaign"], data["session"], data["power_cycle"]) == ("my-camp", "pc-07", 7)
    assert data["kind"] == "gravity-aligned" and data["site"] == {"gravity_mps2": 9.80665}
    assert [r["id"] for r in data["recordings"]] == ["rec-01", "rec-02"]
    assert data["recordings"][0]["files"] == {"dut": "rec 01.csv"}


def test_site_or_gravity_replace_standard_gravity(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, quoted_units, files=1)
    assert main(["init", str(folder), "--site", "32.794,35"]) == 0
    assert "standard gravity" not in capsys.readouterr().err
    assert load_manifest(folder).site.latitude_deg == 32.794
    assert main(["init", str(folder), "--gravity", "9.7955", "--force"]) == 0
    assert load_manifest(folder).g_local == 9.7955
    assert main(["init", str(folder), "--site", "north", "--force"]) == 2
    line = _one_error(capsys.readouterr().err)
    assert line.startswith("ofbe-session: error: --site: expected LAT,HEIGHT_M")


def test_init_never_overwrites_without_force(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, quoted_units, files=1)
    (folder / "session.yaml").write_text("mine\n", encoding="utf-8")
    assert main(["init", str(folder)]) == 2
    line = _one_error(capsys.readouterr().err)
    assert line.startswith(f"ofbe-session: error: {folder / 'session.yaml'}: expected a path that does not "
                           "exist")
    assert "--force" in line
    assert (folder / "session.yaml").read_text(encoding="utf-8") == "mine\n"
    assert main(["init", str(folder), "--force"]) == 0
    assert load_manifest(folder).kind == "gravity-aligned"


def test_an_ambiguous_file_stops_with_the_flag_to_give(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    folder = _session(tmp_path, sample_index, files=1)
    assert main(["init", str(folder)]) == 2
    line = _one_error(capsys.readouterr().err)
    assert line == (f"ofbe-session: error: {folder / 'rec 01.csv'}: 'sample' is a sample index and the file "
                    "states no rate: give --rate HZ")
    assert not (folder / "session.yaml").exists()
    assert main(["init", str(folder), "--rate", "100"]) == 0


def _adc_file(t, acc) -> bytes:
    import numpy as np

    from ofbe_data.io.gravity import G0
    counts = np.rint(acc / G0 * 409.0).astype(np.int64) + 2048
    ms = np.rint(t * 1000).astype(np.int64)
    return "".join(f"{ms[i]} {c[0]} {c[1]} {c[2]}\n" for i, c in enumerate(counts)).encode()


def test_unsigned_counts_need_their_zero_and_scale(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                    ) -> None:
    folder = _session(tmp_path, _adc_file, files=1)
    assert main(["init", str(folder)]) == 2
    line = _one_error(capsys.readouterr().err)
    assert "unsigned counts around mid-scale 2048" in line
    assert line.endswith("give --unit counts --lsb-per-g N --zero-counts Z")
    assert main(["init", str(folder), "--unit", "counts", "--lsb-per-g", "409", "--zero-counts", "2048"]) == 0
    entry = load_manifest(folder).devices["dut"].csv
    assert entry is not None and (entry.lsb_per_g, entry.zero_counts) == (409.0, 2048.0)
    assert main(["check", str(folder)]) == 0


def test_mscip_binary_without_time_needs_the_rate(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                  ) -> None:
    folder = tmp_path / "bin" / "pc-01"
    folder.mkdir(parents=True)
    for k in range(2):
        write_mscip_bin(folder / f"rec-{k + 1}.bin", *simulate(seed=k), None)
    assert main(["init", str(folder)]) == 2
    assert _one_error(capsys.readouterr().err).endswith("without time sub-packets (0x88): give --rate HZ")
    assert main(["init", str(folder), "--rate", "100"]) == 0
    spec = load_manifest(folder).devices["dut"]
    assert (spec.format, spec.bin.sample_rate_hz if spec.bin else None) == ("mscip-bin", 100.0)
    assert main(["check", str(folder)]) == 0


def test_check_says_what_labelling_would_reject(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, quoted_units, files=1)
    assert main(["init", str(folder), "--unit", "m/s2"]) == 0  # a wrong unit, forced
    assert "is the unit m/s2 right?" in capsys.readouterr().err
    assert main(["check", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "would REJECT (implausible-norm)" in out and "values in g declared as m/s2" in out


def test_check_reports_a_bad_manifest_with_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    folder = _session(tmp_path, quoted_units, files=1)
    assert main(["init", str(folder)]) == 0
    text = (folder / "session.yaml").read_text(encoding="utf-8")
    text = text.replace("kind: gravity-aligned", "kind: sideways")
    (folder / "session.yaml").write_text(text, encoding="utf-8")
    capsys.readouterr()
    assert main(["check", str(folder)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    line = next(i for i, t in enumerate(text.splitlines(), 1) if t.startswith("kind:"))
    assert out == [f"{folder}: error: {folder / 'session.yaml'}:{line}: kind: expected one of "
                   "gravity-aligned, rotated, multi-position, found str 'sideways'"]


def test_devices_by_pattern_make_a_rotated_session(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                    ) -> None:
    folder = tmp_path / "tiny" / "rot-pc001"
    shutil.copytree(EXAMPLES / "tiny-rotated" / "rot-pc001", folder, ignore=shutil.ignore_patterns("*.yaml"))
    assert main(["init", str(folder)]) == 2  # one default device cannot hold two formats
    assert "give each kind of file its own --device" in capsys.readouterr().err
    args = ["--device", "sparkfun-1=*sparkfun-1*", "--device", "sparkfun-2=*sparkfun-2.csv",
            "--device", "memsense=rec-*/memsense.csv", "--site", "32.794,35"]
    assert main(["init", str(folder), *args]) == 0
    m = load_manifest(folder)
    assert m.kind == "rotated" and m.power_cycle == 1
    assert {d.id: (d.role, d.format, d.model) for d in m.devices.values()} == {
        "sparkfun-1": ("dut", "ofbe-logger", "ADXL345"), "sparkfun-2": ("dut", "ofbe-logger", "ADXL345"),
        "memsense": ("reference", "mscip-csv", "MS-IMU3025")}
    assert [r.id for r in m.recordings] == ["rec-01", "rec-02"]
    params = tmp_path / "params.yaml"
    params.write_text("label:\n  min_samples: 500\n", encoding="utf-8")
    capsys.readouterr()
    # sparkfun-2 is mounted turned by 90° and init cannot know it: check says so
    assert main(["check", str(folder), "--params", str(params)]) == 1
    out = capsys.readouterr().out
    assert "would REJECT (mount-mismatch)" in out and "would label, reference-rodrigues" in out


def test_two_devices_in_their_own_folders_pair_by_file_name(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "camp" / "two-01"
    for dev in ("left", "right"):
        (folder / dev).mkdir(parents=True)
        for k in range(2):
            (folder / dev / f"take-{k + 1}.csv").write_bytes(quoted_units(*simulate(seed=k)))
    (folder / "notes.md").write_text("hand notes\n", encoding="utf-8")
    assert main(["init", str(folder), "--device", "left=left/*", "--device", "right=right/*",
                 "--model", "left=LIS3DH"]) == 0
    assert "ignored: notes.md (not a data file suffix)" in capsys.readouterr().out
    m = load_manifest(folder)
    assert [(r.id, r.files) for r in m.recordings] == [
        ("take-1", {"left": "left/take-1.csv", "right": "right/take-1.csv"}),
        ("take-2", {"left": "left/take-2.csv", "right": "right/take-2.csv"})]
    assert m.devices["left"].model == "LIS3DH" and m.devices["right"].model == "unknown"
    assert main(["check", str(folder)]) == 0
    assert "would label 4 of 4" in capsys.readouterr().out


def test_usage_problems(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, quoted_units, files=1)
    assert main(["init", str(folder), "--device", "a=*.nothing", "--device", "b=*.csv"]) == 2
    assert "--device a: its pattern matches no data file" in capsys.readouterr().err
    assert main(["init", str(folder), "--kind", "rotated"]) == 2
    assert "give --reference ID" in capsys.readouterr().err
    empty = tmp_path / "c" / "empty"
    empty.mkdir(parents=True)
    assert main(["init", str(empty)]) == 1
    assert "expected data files" in capsys.readouterr().err
    assert main(["check", str(empty)]) == 2


@pytest.mark.slow
def test_console_script_help() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "ofbe_data.cli.session", "init", "--help"],
                          capture_output=True, text=True, check=False, env=env)
    assert done.returncode == 0
    for flag in ("--kind", "--device", "--rate", "--unit", "--lsb-per-g", "--zero-counts", "--site",
                 "--gravity", "--force", "--time-column", "--columns", "--reference", "--time-unit"):
        assert flag in done.stdout


def _two_triads(t: np.ndarray, acc: np.ndarray) -> bytes:
    """One file, two accelerometers (``a1`` in g, ``a2`` in m/s²), semicolons."""
    cols = [t, *(acc.T / G0), *acc.T]
    rows = "".join(";".join(f"{c[i]:.6f}" for c in cols) + "\n" for i in range(t.size))
    return ("t;a1x;a1y;a1z;a2x;a2y;a2z\n" + rows).encode()


def test_two_triads_in_one_file_become_two_devices_that_label(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, _two_triads)
    assert main(["init", str(folder), "--model", "dut=ADXL355"]) == 0
    out = capsys.readouterr().out
    assert "columns [1]: {t: t, ax: a1x, ay: a1y, az: a1z}" in out and "acc_unit [2]: m/s2" in out
    m = load_manifest(folder)
    assert {d.id: (d.model, d.csv.acc_unit if d.csv else None) for d in m.devices.values()} == {
        "dut-1": ("ADXL355", "g"), "dut-2": ("ADXL355", "m/s2")}
    assert [r.files for r in m.recordings] == [{"dut-1": "rec 01.csv", "dut-2": "rec 01.csv"},
                                               {"dut-1": "rec 02.csv", "dut-2": "rec 02.csv"}]
    text = (folder / "session.yaml").read_text(encoding="utf-8")
    assert "# one of 2 accelerometer triads in each file: reads the same file as dut-2, its own ax" in text
    assert main(["check", str(folder)]) == 0
    assert "would label 4 of 4" in capsys.readouterr().out


def test_gyroscope_columns_given_need_their_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _session(tmp_path, lambda t, acc: _two_triads(t, acc).replace(b"a2x;a2y;a2z", b"wx;wy;wz"),
                      files=1)
    cols = "t=t,ax=a1x,ay=a1y,az=a1z,gx=wx,gy=wy,gz=wz"
    assert main(["init", str(folder), "--columns", cols]) == 2
    line = _one_error(capsys.readouterr().err)
    assert line.startswith(f"ofbe-session: error: {folder / 'rec 01.csv'}: the angular-rate columns given "
                           "with --columns: no unit in the names and the values (peak |ω| ")
    assert line.endswith("give --gyro-unit rad/s or deg/s")
    assert main(["init", str(folder), "--columns", cols, "--gyro-unit", "deg/s"]) == 0
    spec = load_manifest(folder).devices["dut"].csv
    assert spec is not None and spec.gyro_unit == "deg/s" and spec.columns["gz"] == "wz"
