"""What other tools make of ofbe's exports: imucal's own calibration applied to raw samples,
and Kalibr's ``imu.yaml`` reader replicated."""

from __future__ import annotations

from pathlib import Path


def imucal_still_norms(result, raw: Path, folder: Path, min_segment_s: float = 0.0) -> list[float]:
    """Export ``result`` (a :class:`~ofbe_data.calibration.results.CalibrationResult`) as an imucal
    file into ``folder``, load it with imucal's own ``load_calibration_info``, apply its
    ``calibrate`` to the raw samples of each of the result's stationary segments (at least
    ``min_segment_s`` long) under the campaign folder ``raw``, and return the norm of each
    segment's mean calibrated reading, m/s²."""
    from datetime import UTC, datetime

    import numpy as np
    from imucal.management import load_calibration_info

    from ofbe_data.calibration import formats as fmt
    from ofbe_data.io.formats import read_device_file
    from ofbe_data.io.manifest import load_manifest

    path = folder / f"{result.stem}.imucal.json"
    path.write_bytes(fmt.imucal_file(result, datetime(2025, 1, 1, tzinfo=UTC)))
    cal = load_calibration_info(path)
    norms = []
    for seg in (s for s in result.segments if s.end_s - s.start_s >= min_segment_s):
        m = load_manifest(raw / seg.session)
        rec = next(r for r in m.recordings if r.id == seg.recording)
        acc = read_device_file(m.file_path(rec, result.device), m.devices[result.device])
        still = (acc.t >= seg.start_s) & (acc.t <= seg.end_s)
        calibrated = cal.calibrate(acc=acc.acc[still], gyr=np.zeros((int(still.sum()), 3)),
                                   acc_unit="m/s^2", gyr_unit="deg/s")[0]
        norms.append(float(np.linalg.norm(calibrated.mean(axis=0))))
    return norms


def kalibr_imu_parameters(data: bytes) -> dict[str, float | str]:
    """What Kalibr's own reader takes from an ``imu.yaml``, replicated line for line.

    ethz-asl/kalibr @ 0b8b9e8, aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py:
    ``ParametersBase.readYaml`` (``yaml.safe_load``), the ``catch_keyerror`` wrapper (a missing key
    → ``RuntimeError("[ImuConfig Reader]: Field '<key>' missing in file: …")``), and
    ``ImuParameters.getRosTopic`` (``checkRosTopic``: a ``str``), ``getUpdateRate``
    (``checkUpdateRate``: ``update_rate <= 0.0`` is an error), ``getAccelerometerStatistics`` and
    ``getGyroStatistics`` (``checkAccelerometerStatistics``/``checkGyroStatistics``: noise density
    and random walk each ``<= 0.0`` is an error; the discrete noise is
    ``noise_density / sqrt(1.0 / update_rate)``). ``IccSensors.py`` (class ``IccImu.__init__``)
    calls both statistics getters unconditionally, so all six fields are required.
    """
    import math

    import yaml

    data_ = yaml.safe_load(data)

    def get(key: str):
        try:
            return data_[key]
        except KeyError as e:
            raise RuntimeError(f"[ImuConfig Reader]: Field {e} missing in file: imu.yaml") from None

    out: dict[str, float | str] = {}
    topic = get("rostopic")
    if not isinstance(topic, str):
        raise RuntimeError("[ImuConfig Reader]: rostopic has to be a string")
    out["rostopic"] = topic
    rate = get("update_rate")
    if rate <= 0.0:
        raise RuntimeError("[ImuConfig Reader]: invalid update_rate")
    out["update_rate"] = rate
    for sensor in ("accelerometer", "gyroscope"):
        density, walk = get(f"{sensor}_noise_density"), get(f"{sensor}_random_walk")
        if density <= 0.0:
            raise RuntimeError(f"[ImuConfig Reader]: invalid {sensor}_noise_density")
        if walk <= 0.0:
            raise RuntimeError(f"[ImuConfig Reader]: invalid {sensor}_random_walk")
        out[f"{sensor}_noise_density"] = density
        out[f"{sensor}_random_walk"] = walk
        out[f"{sensor}_discrete"] = density / math.sqrt(1.0 / rate)
    return out
