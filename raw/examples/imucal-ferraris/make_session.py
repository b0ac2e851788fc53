"""Convert imucal's real Ferraris recording into an ofbe multi-position session, and compare.

Run from the repository root::

    python raw/examples/imucal-ferraris/make_session.py            # (re)write the session
    python raw/examples/imucal-ferraris/make_session.py --compare  # and print the comparison

Source: ``tests/data/imucal-ferraris/annotated_session.csv`` (imucal, MIT; see README.md
beside this script). It holds one BMI160-class IMU at 204.8 Hz, raw counts, with one
``part`` label per sample: six static poses (``x_p``, ``x_a``, ``y_p``, ``y_a``, ``z_p``,
``z_a``: that axis pointing up / down) and three rotations (``*_rot``). Each static pose
becomes one recording of a ``multi-position`` session; the rotations are not static and
are left out. The files are written with the toolkit's own writers, in the generic
``csv`` format, counts as logged and time = sample index / 204.8 Hz.

``--compare`` reads the written session back through the toolkit's readers, fits
:func:`ofbe_data.labelling.multiposition.fit_poses` and prints it beside imucal's own Ferraris result
(``tests/data/imucal-ferraris/example_cal.json``) and the classic six-position estimate;
docs/real-data.md reports and explains the output.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.generic_csv import write_generic_csv
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import (
    CsvMapping,
    DeviceSpec,
    RecordingSpec,
    SessionManifest,
    Site,
    load_manifest,
    write_manifest,
)
from ofbe_data.labelling.multiposition import _jacobian, _residuals, _start, apparent_biases, fit_poses

ROOT = Path(__file__).resolve().parents[3]
SOURCE = ROOT / "tests" / "data" / "imucal-ferraris" / "annotated_session.csv"
IMUCAL_RESULT = ROOT / "tests" / "data" / "imucal-ferraris" / "example_cal.json"
CAMPAIGN = "imucal-ferraris"
SESSION = "ferraris-pc001"
SESSION_DIR = Path(__file__).resolve().parent / SESSION

POSES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
"""Static poses, in recording order: axis x, y or z pointing up (p) or down (a)."""
FS_HZ = 204.8
"""Sampling rate of the source recording, Hz (imucal's example)."""
LSB_PER_G = 2048.0
"""BMI160 at ±16 g: 2048 LSB/g (datasheet); imucal's fitted K_a gives 2046–2107 counts/g."""
GRAVITY_MPS2 = 9.81
"""imucal computed its Ferraris result with g = 9.81 m/s²; the session uses the same value
so that the comparison is like for like (the recording site is not given)."""
DEVICE = "imu"
MAPPING = CsvMapping(columns={"t": "t_s", "ax": "acc_x", "ay": "acc_y", "az": "acc_z"},
                     time_unit="s", acc_unit="counts", lsb_per_g=LSB_PER_G)
TIME_DECIMALS = 6
"""Time stamps are written to 1 µs (the sample period 1/204.8 s = 4882.8125 µs, so a stamp is
off by at most 0.5 µs; more decimals would make the writer print t = 0 as ``0E-10``)."""


def read_source(path: Path = SOURCE) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The static poses of the source file.

    Parameters
    ----------
    path
        imucal's ``annotated_session.csv``.

    Returns
    -------
    dict
        Pose name → ((N,) int sample index, (N, 3) float raw counts), in :data:`POSES` order.
    """
    table = pd.read_csv(path)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for pose in POSES:
        part = table[table["part"] == pose]
        if part.empty:
            raise ValueError(f"{path}: no samples for part {pose!r}")
        out[pose] = (part["samples"].to_numpy(np.int64),
                     part[["acc_x", "acc_y", "acc_z"]].to_numpy(np.float64))
    return out


def session_manifest(folder: Path = SESSION_DIR) -> SessionManifest:
    """The manifest of the converted session: one generic-csv device, one recording per pose."""
    device = DeviceSpec(id=DEVICE, model="BMI160", role="dut", format="csv", csv=MAPPING)
    recordings = tuple(RecordingSpec(id=f"rec-{pose}", files={DEVICE: f"rec-{pose}/{DEVICE}.csv"})
                       for pose in POSES)
    return SessionManifest(folder=folder, campaign=CAMPAIGN, session=SESSION, kind="multi-position",
                           site=Site(gravity_mps2=GRAVITY_MPS2), power_cycle=1,
                           devices={DEVICE: device}, recordings=recordings)


def write_session(folder: Path = SESSION_DIR, source: Path = SOURCE) -> SessionManifest:
    """Write the session folder (manifest and one csv per pose) and return its manifest."""
    poses = read_source(source)
    manifest = session_manifest(folder)
    for rec, pose in zip(manifest.recordings, POSES, strict=True):
        samples, counts = poses[pose]
        target = manifest.file_path(rec, DEVICE)
        target.parent.mkdir(parents=True, exist_ok=True)
        # counts → m/s² with the nominal scale; the writer divides it out again and rounds,
        # so the file holds exactly the source's integer counts.
        write_generic_csv(target, samples / FS_HZ, counts * (G0 / LSB_PER_G), MAPPING,
                          decimals=TIME_DECIMALS)
    write_manifest(manifest)
    return manifest


@dataclass(frozen=True)
class PoseSummary:
    """What the readers give for one pose: samples, mean and a simple static check."""

    recording: str
    n: int
    duration_s: float
    mean: np.ndarray
    """(3,) m/s²."""
    std_mg: np.ndarray
    """(3,) mg, per-axis sample standard deviation."""
    max_moving_std_mg: float
    """mg, largest 1-s moving standard deviation of |a|."""
    half_drift_mg: float
    """mg, |mean of the second half − mean of the first half|."""


def _moving_std(x: np.ndarray, window: int) -> np.ndarray:
    """(N − window + 1,) standard deviation of each run of ``window`` consecutive values."""
    c1 = np.concatenate([[0.0], np.cumsum(x)])
    c2 = np.concatenate([[0.0], np.cumsum(x * x)])
    mean = (c1[window:] - c1[:-window]) / window
    var = (c2[window:] - c2[:-window]) / window - mean * mean
    return np.sqrt(np.maximum(var, 0.0))


def summarise(folder: Path = SESSION_DIR) -> list[PoseSummary]:
    """Read every recording of the session back and summarise it."""
    manifest = load_manifest(folder)
    device = manifest.devices[DEVICE]
    mg = G0 / 1000.0
    out: list[PoseSummary] = []
    for rec in manifest.recordings:
        r = read_device_file(manifest.file_path(rec, DEVICE), device)
        half = r.n // 2
        drift = np.linalg.norm(r.acc[half:].mean(axis=0) - r.acc[:half].mean(axis=0)) / mg
        moving = _moving_std(np.linalg.norm(r.acc, axis=1), int(round(r.fs_hz)))
        out.append(PoseSummary(rec.id, r.n, float(r.t[-1] - r.t[0]), r.acc.mean(axis=0),
                               r.acc.std(axis=0, ddof=1) / mg, float(moving.max() / mg),
                               float(drift)))
    return out


def imucal_offset(path: Path = IMUCAL_RESULT) -> np.ndarray:
    """(3,) m/s², imucal's Ferraris zero-g offset K_a⁻¹·b_a (its model: a_raw = K_a·R_a·a + b_a)."""
    cal = json.loads(path.read_text(encoding="utf-8"))
    return np.linalg.solve(np.array(cal["K_a"]), np.array(cal["b_a"]))


def six_position(means: np.ndarray) -> np.ndarray:
    """(3,) m/s², classic per-axis estimate b_i = (m_i+ + m_i−)/2 from ``means`` in POSES order."""
    return np.array([(means[2 * i, i] + means[2 * i + 1, i]) / 2 for i in range(3)])


def exact_scale_offset(means: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Scale-offset solve with as many unknowns as poses (6), which :func:`fit_poses` refuses.

    Same equations as ``fit_poses(means, g, "scale-offset")``, without the redundant pose:
    the residual is zero by construction and checks nothing, so this is for explanation only.

    Returns
    -------
    tuple
        (3,) m/s² offset b and (3,) diagonal scale s.
    """
    x = least_squares(_residuals, _start(means, g, "scale-offset"), jac=_jacobian, method="lm",
                      args=(means, g, "scale-offset"), xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    return x[:3], x[3:]


def _row(values: np.ndarray, decimals: int, width: int) -> str:
    return " ".join(f"{v:+{width}.{decimals}f}" for v in values)


def compare(folder: Path = SESSION_DIR) -> None:
    """Print pose summaries and the offsets of every method, in m/s² and mg."""
    summaries = summarise(folder)
    g = load_manifest(folder).g_local
    means = np.array([s.mean for s in summaries])
    mg = G0 / 1000.0
    print("pose        n  dur_s  std_mg(x,y,z)     max1s_std|a|_mg  half_drift_mg")
    for s in summaries:
        print(f"{s.recording:8s} {s.n:5d} {s.duration_s:6.2f}  {np.array2string(s.std_mg, precision=2)}"
              f"  {s.max_moving_std_mg:6.2f}  {s.half_drift_mg:6.3f}")
    fits = {model: fit_poses(means, g, model) for model in ("offset", "scale-offset")}
    rows = {"imucal Ferraris": imucal_offset(), "six-position": six_position(means),
            "offset LS": fits["offset"].offset, "scale-offset LS": fits["scale-offset"].offset}
    exact_b, exact_s = exact_scale_offset(means, g)
    rows["scale-offset exact"] = exact_b
    print(f"\n{'method':19s}  {'offset m/s² (x, y, z)':29s}  offset mg (x, y, z)")
    for name, b in rows.items():
        print(f"{name:19s}  {_row(b, 5, 9)}  {_row(b / mg, 2, 7)}")
    for model, fit in fits.items():
        print(f"\n{model}: determined={fit.determined} reason={fit.reason!r} "
              f"residual_rms={fit.residual_rms:.4g} m/s² condition={fit.condition:.3g} "
              f"scale={np.array2string(fit.scale, precision=5)}")
    print(f"\nscale-offset exact (6 poses, 6 unknowns): scale={np.array2string(exact_s, precision=5)}")
    if fits["offset"].determined:
        app = apparent_biases(means, fits["offset"], g)
        print("\napparent biases (offset fit), m/s²:")
        for s, b in zip(summaries, app, strict=True):
            print(f"  {s.recording:8s} {np.array2string(b, precision=4)}")


def main(argv: list[str] | None = None) -> int:
    """Command-line entry: write the session, check it reads back, optionally compare."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--compare", action="store_true", help="also print the comparison")
    args = parser.parse_args(argv)
    manifest = write_session()
    n = sum(read_device_file(manifest.file_path(rec, DEVICE), manifest.devices[DEVICE]).n
            for rec in load_manifest(manifest.folder).recordings)
    print(f"wrote {manifest.folder} ({len(manifest.recordings)} recordings, {n} samples)")
    if args.compare:
        compare(manifest.folder)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
