"""Tap synchronisation: known offsets and drifts, the committed examples, and fallbacks."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.recording import ReadDiagnostics, Recording
from ofbe_data.labelling.sync import SyncError, synchronise

START = datetime(2025, 3, 14, 10, 0, tzinfo=UTC)


def _tap(t: np.ndarray, t0: float, amp: float, f: float, direction: np.ndarray) -> np.ndarray:
    s = np.clip(t - t0, 0.0, None)
    return (amp * np.sin(2 * np.pi * f * s) * np.exp(-s / 0.05) * (t >= t0))[:, None] * direction


def _recording(t_clock: np.ndarray, acc: np.ndarray, start_utc: datetime | None) -> Recording:
    n = t_clock.shape[0]
    diag = ReadDiagnostics(Path("x.csv"), 0, n, n)
    return Recording(Path("x.csv"), "csv", t_clock, acc, np.zeros(n, bool), np.arange(n) + 2,
                     start_utc, None, {}, diag)


def _pair(offset: float, drift_ppm: float, stamps: bool = True, taps: tuple[float, ...] = (3.0, 90.0),
          seed: int = 0, mount: np.ndarray | None = None) -> tuple[Recording, Recording]:
    """A reference at 200 Hz and a DUT at 150 Hz on a clock t_dut = offset + (1 + drift)·t_ref."""
    rng = np.random.default_rng(seed)
    mount = np.eye(3) if mount is None else mount
    t_ref = np.arange(0, 94.0, 1 / 200)
    gravity = np.array([0.0, 0.0, 9.79])
    dirs = [np.array([0.6, 0.0, 0.8]), np.array([0.0, -1.0, 0.0])]
    ref_acc = gravity + sum((_tap(t_ref, t0, 15.0, 31.0, d) for t0, d in zip(taps, dirs, strict=False)),
                            np.zeros((t_ref.size, 3)))
    ref_acc = ref_acc + rng.normal(0, 0.005, ref_acc.shape)
    rate = 1 + drift_ppm * 1e-6
    t_local = np.arange(0.4, 93.6, 1 / 150)  # DUT polls, reference time
    t_local = t_local + rng.uniform(-2e-4, 2e-4, t_local.size)
    dut_acc = gravity + sum((_tap(t_local, t0, 15.0, 31.0, d) for t0, d in zip(taps, dirs, strict=False)),
                            np.zeros((t_local.size, 3)))
    dut_acc = dut_acc @ mount.T + rng.normal(0, 0.035, dut_acc.shape)
    t_dut = offset + rate * t_local
    host = START + timedelta(seconds=float(t_local[0]) + rng.uniform(-0.1, 0.1))
    return (_recording(t_dut, dut_acc, host if stamps else None),
            _recording(t_ref, ref_acc, START if stamps else None))


@pytest.mark.parametrize("offset, drift_ppm", [(1234.5678, 0.0), (17.0, 45.0), (4000.25, -50.0)])
def test_known_offset_and_drift_are_recovered(offset, drift_ppm):
    dut, ref = _pair(offset, drift_ppm, seed=int(offset))
    s = synchronise(dut, ref)
    assert s.method == "taps" and s.warning == ""
    assert s.offset_s == pytest.approx(offset, abs=0.5e-3)
    assert s.drift_ppm == pytest.approx(drift_ppm, abs=10.0)
    assert s.residual_s < 1e-3
    assert s.taps_ref_s == pytest.approx((3.0, 90.0), abs=0.03)
    assert float(s.to_reference(s.to_device(12.5))) == pytest.approx(12.5, abs=1e-9)


def test_taps_are_found_without_header_stamps_and_through_a_rotated_mount():
    mount = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]])
    dut, ref = _pair(55.5, 20.0, stamps=False, mount=mount)
    s = synchronise(dut, ref, mount)
    assert s.method == "taps" and np.isnan(s.coarse_offset_s)
    assert s.offset_s == pytest.approx(55.5, abs=0.5e-3)


def test_a_wrong_mount_in_the_manifest_is_noticed():
    dut, ref = _pair(55.5, 0.0, mount=np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]]))
    s = synchronise(dut, ref, np.diag([1.0, 1.0, 1.0]))
    assert s.method == "taps" and "did not match through the nominal mount" in s.warning
    assert s.offset_s == pytest.approx(55.5, abs=10e-3)  # envelope alignment only


def test_without_taps_the_header_stamps_align_with_a_warning():
    dut, ref = _pair(100.0, 0.0, taps=())
    s = synchronise(dut, ref)
    assert s.method == "utc" and s.drift_ppm == 0.0 and np.isnan(s.residual_s)
    assert s.warning == ("0 tap(s) found in the reference, 2 needed; aligned by header UTC stamps "
                         "only (±0.1 s, drift unknown)")
    assert s.offset_s == pytest.approx(100.0, abs=0.11)


def test_without_taps_or_stamps_synchronisation_fails_clearly():
    dut, ref = _pair(100.0, 0.0, taps=(), stamps=False)
    with pytest.raises(SyncError, match=r"cannot align x\.csv with x\.csv: 0 tap\(s\) found in the "
                                        r"reference, 2 needed, and a header UTC stamp is missing"):
        synchronise(dut, ref)


def test_examples_align_within_a_fraction_of_a_dut_sample(examples: Path):
    campaign = examples / "tiny-rotated"
    errors = []
    for folder in sorted(campaign.glob("rot-*")):
        m = load_manifest(folder)
        truth = json.loads((campaign / "_truth" / f"{m.session}.json").read_text())
        assert m.reference is not None
        for rec in m.recordings:
            ref = read_device_file(m.file_path(rec, m.reference.id), m.reference)
            for dev in m.duts:
                s = synchronise(read_device_file(m.file_path(rec, dev.id), dev), ref, dev.reference_to_sensor)
                true = truth["recordings"][rec.id]["devices"][dev.id]["clock_offset_s"]
                errors.append(s.offset_s - true)
    assert len(errors) == 8
    assert np.max(np.abs(errors)) < 0.3 / 150  # well inside one sample period (6.7 ms)
