"""Continuous multi-position recordings (issue 13): the simulator's many-pose files, labelled.

The ``tiny-multi-position-continuous`` profile (3 power cycles × 2 recordings of 12–24 poses,
1–6 s of rest, 1–3 s of handling) is simulated, labelled with the default
:class:`~ofbe_data.labelling.labels.LabelParams`, and held to its truth:

- **Poses.** Every detected pose lies inside one true rest interval, widened by the labeller's
  ``margin_s`` at both ends, and overlaps no other (none merged across a handling motion);
  every true pose whose rest (first to last logged sample) lasts at least ``min_pose_s`` (1 s)
  is found exactly once.
- **Offsets.** The pose fit's offset of a power cycle is compared with the mean true zero-g
  offset of the poses it used. What it may miss by is derived per power cycle and axis from the
  truth: (a) the *model error*, the offset the same fit (same model, poses grouped by direction
  as the labeller groups them) finds on the noise-free pose means A·u_k·g + b_k: the fit's
  diagonal scale cannot represent the sensor's 0.3° cross-axis terms, which leave up to ~1.4 mg
  at 35–64 poses; and (b) noise: per pose σ_i/√n (σ = noise rms and the 3.83 mg quantisation
  step, 3.7 / 3.7 / 5.3 mg per sample, n the pose's samples) projected on its direction and
  propagated through the fit's Jacobian, 0.055–0.07 mg per axis here. The fitted offset must lie
  within 5 noise standard deviations of the model-limited one, and the offsets of the campaign
  within 1 mg rms of the truth (measured: 0.46 mg; on ``multi-position-continuous``, 16 fits of
  35–64 poses, 0.53 mg).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest
from ofbe_data.labelling.labels import LabelParams, SessionLabels, label_session
from ofbe_data.labelling.multiposition._fit import fit_poses, min_poses, residual_jacobian
from ofbe_data.labelling.multiposition._search import distinct_directions
from ofbe_data.simulator import continuous as continuous_module
from ofbe_data.simulator import load_config, simulate_campaign

PROFILE = "tiny-multi-position-continuous"
MG = G0 / 1000.0
LSB = G0 / 256.0
PARAMS = LabelParams()
MARGIN_S = PARAMS.poses.margin_s
FINDABLE_S = PARAMS.poses.min_pose_s
"""Shortest rest the labeller is required to find, s."""
NOISE_SIGMAS = 5.0

Campaign = dict[str, tuple[SessionLabels, dict[str, Any]]]
"""Session id → its labels and its truth."""


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Campaign]:
    out = tmp_path_factory.mktemp("raw") / PROFILE
    simulate_campaign(PROFILE, out, progress=False)
    sessions: Campaign = {}
    for manifest in sorted(out.glob("*/session.yaml")):
        labels = label_session(manifest.parent, PARAMS)
        truth = json.loads((out / "_truth" / f"{labels.manifest.session}.json").read_text())
        sessions[labels.manifest.session] = (labels, truth)
    return out, sessions


def _true_poses(truth: dict[str, Any], recording: str, device: str) -> list[dict[str, Any]]:
    return truth["recordings"][recording]["devices"][device]["poses"]


def _overlapping(row: dict[str, Any], poses: list[dict[str, Any]], widen: float = 0.0) -> list[int]:
    a, b = row["segment_start_s"], row["segment_end_s"]
    return [k for k, p in enumerate(poses) if a <= p["t_device"][1] + widen and b >= p["t_device"][0] - widen]


# --- the simulated campaign -----------------------------------------------------------------------


def test_recordings_hold_the_configured_poses_and_handling(campaign: tuple[Path, Campaign]) -> None:
    _, sessions = campaign
    c = load_config(PROFILE).continuous
    assert c is not None
    starts = set()
    for _, truth in sessions.values():
        for rec in truth["recordings"].values():
            poses = rec["poses"]
            assert c.poses[0] <= len(poses) <= c.poses[1]
            starts.add(rec["start"])
            rests = np.array([p["t_ref"] for p in poses])
            lengths = rests[:, 1] - rests[:, 0]
            quiet = rec["start"] == "quiet"
            lead = c.quiet_s if quiet else (0.0, 0.0)
            assert c.pose_s[0] + lead[0] - 1e-9 <= lengths[0] <= c.pose_s[1] + lead[1] + 1e-9
            assert np.all((lengths[1:] >= c.pose_s[0] - 1e-9) & (lengths[1:] <= c.pose_s[1] + 1e-9))
            handling = np.array(rec["handling_t_ref"])
            assert len(handling) == len(poses) + (0 if quiet else 1)
            gaps = handling[:, 1] - handling[:, 0]
            assert np.all((gaps >= c.handling_s[0] - 1e-9) & (gaps <= c.handling_s[1] + 1e-9))
            # rest and handling alternate and fill the recording
            events = sorted([*map(tuple, rests), *map(tuple, handling)])
            assert events[0][0] == 0.0 and events[-1][1] == pytest.approx(rec["duration_s"])
            assert all(b == pytest.approx(a2) for (_, b), (a2, _) in zip(events, events[1:], strict=False))
            # directions spread over the sphere: every face within 60° of a pose
            u = np.array([p["u_plate"] for p in poses])
            np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-12)
            faces = np.vstack([np.eye(3), -np.eye(3)])
            assert np.all(np.max(faces @ u.T, axis=1) >= 0.5)
            assert rec["taps_t_ref"] == [] and rec["nominal"] == {}
    assert starts == {"quiet", "motion"}


def test_the_files_hold_what_the_truth_says(campaign: tuple[Path, Campaign]) -> None:
    """Over each true rest: mean reading − A·u·g equals the pose's offset within noise/√n; the
    recording-level keys of a one-pose recording are there and describe the first pose."""
    out, sessions = campaign
    z_all = []
    for session, (_, truth) in sessions.items():
        manifest = load_manifest(out / session / "session.yaml")
        g = truth["g_local"]
        for rec in manifest.recordings:
            for dut in manifest.duts:
                r = read_device_file(manifest.file_path(rec, dut.id), dut)
                dev = truth["devices"][dut.id]
                tr = truth["recordings"][rec.id]["devices"][dut.id]
                a = np.array(dev["A"])
                sigma = np.sqrt(np.array(dev["noise_rms"]) ** 2 + LSB**2 / 12)
                for p in tr["poses"]:
                    seg = (r.t >= p["t_device"][0] - 1e-6) & (r.t <= p["t_device"][1] + 1e-6)
                    assert abs(int(seg.sum()) - p["samples"]) <= 2  # dropped or garbled lines
                    resid = r.acc[seg].mean(axis=0) - a @ np.array(p["u_sensor"]) * g - np.array(p["offset"])
                    z_all.append(resid / (sigma / np.sqrt(seg.sum())))
                    np.testing.assert_allclose(np.array(p["apparent_bias"]) + g * np.array(p["u_nominal"]),
                                               a @ np.array(p["u_sensor"]) * g + np.array(p["offset"]),
                                               atol=1e-9)
                first = tr["poses"][0]
                for key in ("offset", "apparent_bias", "u_sensor", "u_nominal"):
                    assert tr[key] == first[key]
                assert tr["stationary_samples"] == first["samples"]
    z = np.array(z_all)
    assert np.abs(z).max() < 5.0
    assert z.std() == pytest.approx(1.0, abs=0.2)


# --- the labeller against the truth ---------------------------------------------------------------


def test_every_pose_is_found_once_and_none_is_merged(campaign: tuple[Path, Campaign]) -> None:
    _, sessions = campaign
    findable = found = 0
    for labels, truth in sessions.values():
        assert labels.rejections == []
        by_file: dict[tuple[str, str], list[dict[str, Any]]] = {}
        for row in labels.rows:
            by_file.setdefault((row["recording"], row["device"]), []).append(row)
        for rec_id, rec in truth["recordings"].items():
            for device in rec["devices"]:
                rows = by_file.get((rec_id, device), [])
                poses = _true_poses(truth, rec_id, device)
                assert [r["pose"] for r in rows] == list(range(len(rows)))
                for row in rows:
                    hits = _overlapping(row, poses)
                    assert len(hits) == 1, f"{rec_id} pose {row['pose']} overlaps true poses {hits}"
                    k = hits[0]
                    lo, hi = poses[k]["t_device"]
                    assert lo - MARGIN_S <= row["segment_start_s"] and row["segment_end_s"] <= hi + MARGIN_S
                for k, p in enumerate(poses):
                    hits = [r for r in rows if k in _overlapping(r, poses)]
                    assert len(hits) <= 1, f"{rec_id}: true pose {k} found {len(hits)} times"
                    if p["t_device"][1] - p["t_device"][0] >= FINDABLE_S:
                        findable += 1
                        assert len(hits) == 1, f"{rec_id}: true pose {k} ({p['t_device']}) not found"
                    found += len(hits)
    assert findable >= 80 and found >= findable


def _offset_check(rows: list[dict[str, Any]], truth: dict[str, Any], device: str,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Fit error, model error and noise standard deviation of one device's offset (m/s², per axis),
    and the number of distinct true directions."""
    g = truth["g_local"]
    dev = truth["devices"][device]
    a = np.array(dev["A"])
    sigma2 = np.array(dev["noise_rms"]) ** 2 + LSB**2 / 12
    exact, offsets, units, n = [], [], [], []
    for row in rows:
        poses = _true_poses(truth, row["recording"], device)
        p = poses[_overlapping(row, poses)[0]]
        u = np.array(p["u_sensor"])
        exact.append(a @ u * g + np.array(p["offset"]))
        offsets.append(p["offset"])
        units.append(u)
        n.append(row["n_samples"])
    exact_means, u_all = np.array(exact), np.array(units)
    models = {r["fit_model"] for r in rows}
    assert len(models) == 1
    model = models.pop()
    true_offset = np.mean(offsets, axis=0)
    exact_fit = fit_poses(exact_means, g, model)  # every pose as it is, as the labeller fits them
    model_error = exact_fit.offset - true_offset
    # noise: each pose mean's error along its direction, through the fit's Jacobian at the
    # noise-free solution (the true noise variances, not the fit's own standard errors)
    var = np.array([float(np.sum(u_all[i] ** 2 * sigma2)) / n[i] for i in range(len(rows))])
    jac = residual_jacobian(exact_fit.params, exact_means, np.zeros(len(rows)), g, model)
    inv = np.linalg.inv(jac.T @ jac)
    sd = np.sqrt(np.diag(inv @ jac.T @ (jac * var[:, None]) @ inv)[:3])
    fitted = np.array([rows[0][f"offset_{axis}"] for axis in "xyz"])
    return fitted - true_offset, model_error, sd, distinct_directions(exact_means)


def test_pose_fit_offsets_are_within_a_milligravity_of_the_truth(campaign: tuple[Path, Campaign]) -> None:
    _, sessions = campaign
    errors = []
    for labels, truth in sessions.values():
        for device in truth["devices"]:
            rows = [r for r in labels.rows if r["device"] == device]
            error, model_error, sd, distinct = _offset_check(rows, truth, device)
            # 1 % scale and 0.3° non-orthogonality errors: the ladder climbs as far as the poses allow
            expected = "full" if distinct >= min_poses("full") else "scale-offset"
            assert rows[0]["fit_model"] == expected, rows[0]["fit_model_reason"]
            assert np.all(np.abs(error - model_error) <= NOISE_SIGMAS * sd), (error, model_error, sd)
            assert np.all(sd < 0.15 * MG)
            errors.append(error)
    rms = np.sqrt(np.mean(np.array(errors) ** 2))
    assert rms <= 1.0 * MG, f"offsets {rms / MG:.3f} mg rms from the truth"


# --- configuration and the one-pose campaigns -----------------------------------------------------


def _rounded(value: Any, decimals: int) -> Any:
    if isinstance(value, float):
        return round(value, decimals)
    if isinstance(value, dict):
        return {k: _rounded(v, decimals) for k, v in value.items()}
    if isinstance(value, list):
        return [_rounded(v, decimals) for v in value]
    return value


def _digest(root: Path) -> str:
    """sha256 over every file's path and sha256, in path order; a truth JSON by its values rounded to
    9 decimals. The truth files hold values rounded to 12 decimals from elementary functions (sin,
    cos, exp) whose last bit differs between CPUs (numpy's AVX-512 routines against its others): one
    value in thousands then rounds the other way at 12 decimals (seen on one of 24 truth files of this
    campaign); the data files and the truth to 9 decimals are the same bytes on every machine."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.is_file():
            data = p.read_bytes()
            if p.parent.name == "_truth" and p.suffix == ".json":
                data = json.dumps(_rounded(json.loads(data), 9), sort_keys=True).encode()
            h.update(f"{p.relative_to(root).as_posix()}\0{hashlib.sha256(data).hexdigest()}\n".encode())
    return h.hexdigest()


MULTI_POSITION_DIGEST = "4ceec805882b6e80d7301ce62598c552079618128ca01c6963014afa6f396295"
"""``_digest`` of ``multi-position`` (seed 3) written to a folder of that name: 24 positions per
power cycle since the calibration model (9 before; the digest of that profile, written before
the ``continuous`` option existed, was bb2ead51…, and this test held it until the profile changed).
The truth files enter it rounded to 9 decimals since 2026-11-27 (was 0e4b2343… with the files'
own bytes, which one CPU without AVX-512 did not reproduce: see :func:`_digest`)."""


@pytest.mark.slow
def test_one_pose_campaigns_never_take_the_continuous_path(examples: Path, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("continuous code path taken")

    for name in ("draw_pose_plans", "draw_motion", "specific_force", "pose_truth", "recording_truth"):
        monkeypatch.setattr(continuous_module, name, refuse)
    simulate_campaign("tiny-multi-position", tmp_path / "tiny-multi-position", progress=False)
    assert _digest(tmp_path / "tiny-multi-position") == _digest(examples / "tiny-multi-position")
    simulate_campaign("multi-position", tmp_path / "multi-position", progress=False)
    assert _digest(tmp_path / "multi-position") == MULTI_POSITION_DIGEST
    assert "continuous" not in (tmp_path / "multi-position" / "_truth" / "simulation.yaml").read_text()
    with pytest.raises(AssertionError, match="continuous code path taken"):  # the patch holds
        simulate_campaign(PROFILE, tmp_path / "continuous", progress=False)


@pytest.mark.parametrize("overrides, key", [
    ({"kind": "gravity-aligned", "tilts": {"mode": "level"}, "taps": {"enabled": False}}, "continuous"),
    ({"continuous": {"poses": [0, 5]}}, "continuous.poses"),
    ({"continuous": {"poses": [8, 6]}}, "continuous.poses"),
    ({"continuous": {"pose_s": [2.0, 1.0]}}, "continuous.pose_s"),
    ({"continuous": {"handling_s": [0.0, 1.0]}}, "continuous.handling_s"),
    ({"continuous": {"quiet_start_prob": 1.5}}, "continuous.quiet_start_prob"),
    ({"continuous": {"pose_s": [1.0, 90000.0]}}, "continuous"),
    ({"continuous": {"tilt": 1.0}}, "continuous.tilt"),
])
def test_continuous_config_errors_name_the_key(overrides: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError, match=rf": {key}: expected"):
        load_config(PROFILE, overrides)


def test_a_quiet_sensor_finds_every_pose_as_a_noisy_one_does(tmp_path: Path) -> None:
    """Issue 22: on a very quiet sensor the threshold followed its own noise floor below what a
    still pose holds (drift, settling) and dropped most poses (44 of 116 here with a 10 µg
    floor bound). The floor is raised to 0.5 mg: every pose of the truth that lasts the
    shortest pose is found, once."""
    import dataclasses

    cfg = load_config(PROFILE)
    quiet = dataclasses.replace(cfg, dut_model=dataclasses.replace(
        cfg.dut_model, noise_mg=(0.025, 0.025, 0.025), lsb_per_g=256000.0))  # ADXL355-like
    simulate_campaign(quiet, tmp_path / "c", seed=3, jobs=1, progress=False)
    findable = found = 0
    for session in sorted(p for p in (tmp_path / "c").iterdir() if p.is_dir() and not p.name.startswith("_")):
        truth = json.loads((tmp_path / "c" / "_truth" / f"{session.name}.json").read_text())
        labels = label_session(session)
        assert labels.rejections == []
        for rec_id in truth["recordings"]:
            poses = _true_poses(truth, rec_id, "sparkfun-1")
            rows = [r for r in labels.rows if r["recording"] == rec_id]
            for k, p in enumerate(poses):
                hits = [r for r in rows if k in _overlapping(r, poses)]
                assert len(hits) <= 1, (session.name, rec_id, k)
                findable += p["t_device"][1] - p["t_device"][0] >= FINDABLE_S
                found += len(hits)
    assert found >= findable >= 100, (found, findable)
