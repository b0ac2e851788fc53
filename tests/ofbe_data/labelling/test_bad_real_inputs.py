"""Bad inputs a lab brings (issue 13's list), through ofbe-label on a multi-position session of
a real generic csv: each gives its exact error or recorded rejection, and nothing partial."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.label import main as label_main
from tests.helpers.paths import EXAMPLES

REAL = EXAMPLES / "imucal-ferraris" / "ferraris-continuous" / "rec-01" / "imu2.csv"
MANIFEST = """format: ofbe-session/1
campaign: c
session: {session}
kind: multi-position
site: {{gravity_mps2: 9.81}}
power_cycle: 1
devices:
  imu:
    model: X
    role: dut
    format: {fmt}
{keys}recordings:
  - id: r1
    files: {{imu: r1/{name}}}
"""
CSV_KEYS = ("    columns: {{t: n_samples, ax: acc_x, ay: acc_y, az: acc_z}}\n    time_unit: samples\n"
            "    sample_rate_hz: 102.4\n    acc_unit: {unit}\n")


def _session(root: Path, name: str, data: bytes, *, fmt: str = "csv", keys: str | None = None,
             file: str = "imu.csv", unit: str = "m/s2") -> Path:
    folder = root / "c" / name
    (folder / "r1").mkdir(parents=True)
    (folder / "r1" / file).write_bytes(data)
    (folder / "session.yaml").write_text(MANIFEST.format(session=name, fmt=fmt, file=file, name=file,
                                                         keys=CSV_KEYS.format(unit=unit) if keys is None
                                                         else keys), encoding="utf-8")
    return folder


def _csv(acc: np.ndarray, scale: float = 1.0) -> bytes:
    rows = "".join(f"{i},{a / scale:.5f},{b / scale:.5f},{c / scale:.5f}\n"
                   for i, (a, b, c) in enumerate(acc))
    return ("n_samples,acc_x,acc_y,acc_z\n" + rows).encode()


RNG = np.random.default_rng(0)
_T = np.arange(3000)
MOTION = (np.column_stack([5 * np.sin(_T / 7), 5 * np.cos(_T / 5), 9.8 + 3 * np.sin(_T / 3)])
          + RNG.normal(0.0, 0.5, (3000, 3)))
STILL = np.array([0.1, 0.2, 9.8]) + RNG.normal(0.0, 0.04, (3000, 3))

ERRORS = [
    ("empty", b"", {}, "{file}: expected a column line and data lines, found an empty file"),
    ("header-only", b"n_samples,acc_x,acc_y,acc_z\n", {},
     "{file}:1: expected at least one valid data line, found none"),
    ("wrong-delimiter", REAL.read_bytes().replace(b",", b";"), {},
     "{file}:1: expected columns n_samples, acc_x, acc_y, acc_z, found "
     "'n_samples;gyr_x;gyr_y;gyr_z;acc_x;acc_y;acc_z' (missing n_samples, acc_x, acc_y, acc_z)"),
    ("counts-without-lsb", REAL.read_bytes(), {"unit": "counts"},
     "{manifest}:8: devices.imu.lsb_per_g: expected this key, found it missing"),
    ("garbage-mscip-bin", bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)),
     {"fmt": "mscip-bin", "keys": "    sample_rate_hz: 200\n", "file": "m.bin"},
     "{file}: expected MSCIP packets (A5 A5 <type> <length> <sub-packets> <2-byte Fletcher checksum>), "
     "found no valid packet in 5000 bytes"),
]


@pytest.mark.parametrize(("name", "data", "options", "message"), ERRORS, ids=[e[0] for e in ERRORS])
def test_unreadable_input_is_one_line_and_writes_nothing(tmp_path, capsys, name, data, options,
                                                        message) -> None:
    folder = _session(tmp_path, name, data, **options)
    out = tmp_path / "out"
    assert label_main([str(folder), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    expected = message.format(file=folder / "r1" / options.get("file", "imu.csv"),
                              manifest=folder / "session.yaml")
    assert err.startswith(f"ofbe-label: error: {expected}") and err.count("\n") == 1, err
    assert not out.exists() or not any(p.is_file() for p in out.rglob("*"))


REJECTIONS = [
    ("all-motion", _csv(MOTION), "no-stationary-segment",
     "poses: no static part: the noise floor (from the initial quiet stretch) is 3.17 m/s² per axis "
     "(322.9 mg), above max_noise_mps2 = 0.3 m/s²"),
    ("single-pose", _csv(STILL), "multi-position-undetermined",
     "poses: no threshold multiplier gives static poses that determine the pose fit (4 at least; static "
     "intervals of 1 s or more per multiplier: ×2: 1, ×3: 1"),
    ("g-declared-m-s2", _csv(STILL, 9.81), "implausible-norm",
     "‖mean‖ = 0.9992 m/s² is 0.102 × g_local (9.8100 m/s²), more than 30% away: likely values in g "
     "declared as m/s2"),
]


@pytest.mark.parametrize(("name", "data", "reason", "detail"), REJECTIONS, ids=[r[0] for r in REJECTIONS])
def test_unlabellable_input_is_a_recorded_rejection(tmp_path, capsys, name, data, reason, detail) -> None:
    import json

    folder = _session(tmp_path, name, data)
    out = tmp_path / "out"
    assert label_main([str(folder), "--out", str(out), "--quiet"]) == 1
    assert capsys.readouterr().err == (f"ofbe-label: error: no recording was labelled (1 {reason}; see the "
                                       f"<session>.rejected.json files in {out})\n")
    # no label file of no label (issue 33): the rejection file says why
    written = sorted(p.name for p in (out / "c").iterdir())
    assert written == sorted(["campaign_fit.json", f"{name}.rejected.json"])
    (rejection,) = json.loads((out / "c" / f"{name}.rejected.json").read_text())["rejected"]
    assert rejection["reason"] == reason and rejection["detail"].startswith(detail), rejection["detail"]
