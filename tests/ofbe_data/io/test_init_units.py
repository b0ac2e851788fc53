"""``ofbe-session init``: a unit the column names state that the values plainly contradict is
never written; init stops with one line naming both readings and the flag."""

from __future__ import annotations

import numpy as np

from ofbe_data.cli.session import main
from ofbe_data.io.manifest import load_manifest


def _file(folder, unit: str, level: float) -> None:
    """A still 30 s file at 100 Hz whose header says ``unit`` and whose values rest at ``level``."""
    rng = np.random.default_rng(0)
    acc = np.array([0.03, -0.02, 1.0]) * level + rng.normal(0, 0.002 * level, (3000, 3))
    rows = [f"{i / 100:.2f},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}" for i, a in enumerate(acc)]
    folder.mkdir(parents=True)
    (folder / "rec.csv").write_text(f"t (s),ax ({unit}),ay ({unit}),az ({unit})\n" + "\n".join(rows) + "\n")


def test_a_g_header_over_m_s2_values_is_refused_with_both_readings(tmp_path, capsys) -> None:
    folder = tmp_path / "s1"
    _file(folder, "g", 9.48)
    assert main(["init", str(folder)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "warning" not in line]
    assert len(err) == 1 and err[0].startswith(f"ofbe-session: error: {folder / 'rec.csv'}: the column names "
                                                "say g, but ‖mean‖ at rest (the quietest ")
    assert err[0].endswith(" = 9.49 g in g, and 0.9676 g in m/s2: give --unit m/s2 if the values are m/s2, "
                           "--unit g if they are"), err[0]
    assert not (folder / "session.yaml").exists()
    assert main(["init", str(folder), "--unit", "m/s2"]) == 0
    assert load_manifest(folder).duts[0].csv.acc_unit == "m/s2"


def test_a_header_unit_the_values_agree_with_is_taken(tmp_path) -> None:
    for unit, level in (("g", 1.0), ("m/s2", 9.81), ("mg", 1000.0)):
        folder = tmp_path / unit.replace("/", "_")
        _file(folder, unit, level)
        assert main(["init", str(folder)]) == 0
        assert load_manifest(folder).duts[0].csv.acc_unit == unit


def test_the_files_banner_gives_model_and_range(tmp_path, capsys) -> None:
    """'# ADXL345 on an Arduino, range +/-4g' above the data: init writes model ADXL345 and
    range_g 4 and says which line said so; a banner naming two chips gives no model."""
    rng = np.random.default_rng(1)
    acc = np.array([0.02, -0.01, 1.0]) + rng.normal(0, 0.003, (3000, 3))
    rows = "".join(f"{i * 10},{a[0]:.4f},{a[1]:.4f},{a[2]:.4f}\n" for i, a in enumerate(acc))
    folder = tmp_path / "s1"
    folder.mkdir()
    banner = "# ADXL345 on an Arduino Uno, range +/-4g, ODR 100 Hz\n"
    (folder / "rec.csv").write_text(banner + "t_ms,ax_g,ay_g,az_g\n" + rows)
    assert main(["init", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "line 1: '# ADXL345 on an Arduino Uno, range +/-4g, ODR 100 Hz'" in out
    dut = load_manifest(folder).duts[0]
    assert dut.model == "ADXL345" and dut.csv.range_g == 4.0
    other = tmp_path / "s2"
    other.mkdir()
    (other / "rec.csv").write_text("# ADXL345 and MPU-6050 side by side\nt_ms,ax_g,ay_g,az_g\n" + rows)
    assert main(["init", str(other)]) == 0
    assert load_manifest(other).duts[0].model == "unknown"
