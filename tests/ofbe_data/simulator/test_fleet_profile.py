"""The ``fleet`` simulator profile (docs/scale.md, "The fleet profile") and the compact
``duts: {count: N, prefix: ...}`` form it uses: hundreds of devices, tens of power cycles,
short level recordings that the default labelling parameters accept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.errors import ConfigError
from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.dataset.reader import load_dataset
from ofbe_data.dataset.store import DEFAULT_SHARD_WINDOWS
from ofbe_data.dataset.windows import n_windows
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.labelling.store import read_labels
from ofbe_data.simulator import builtin_profiles, load_config, simulate_campaign
from ofbe_data.simulator.config import DutConfig, expand_duts, load_config_from


def test_the_fleet_profile() -> None:
    cfg = load_config("fleet")
    assert {"fleet", "tiny-fleet"} <= set(builtin_profiles())
    assert cfg.kind == "gravity-aligned" and cfg.reference is None and not cfg.taps.enabled
    assert [d.id for d in cfg.duts] == [f"unit-{k:03d}" for k in range(1, 301)]
    assert all(d == DutConfig(d.id) for d in cfg.duts)  # z up, the default mounting
    assert cfg.sessions == 20 and cfg.recordings_per_session == 1
    # long enough for the labeller's default minimum (4500 samples = 30 s at 150 Hz)
    assert cfg.stationary_s[0] >= 31.0
    assert cfg.stationary_s[0] * cfg.dut_model.rate_hz > LabelParams().min_samples
    # with the paper's windowing, one window per recording: 6000 windows, above one shard
    per = n_windows(int(cfg.stationary_s[0] * cfg.dut_model.rate_hz) - 10, 3000, 3000)
    assert per == 1 and len(cfg.duts) * cfg.sessions * per > DEFAULT_SHARD_WINDOWS


@pytest.mark.slow
def test_tiny_fleet_simulates_labels_and_builds(tmp_path: Path) -> None:
    cfg = load_config("tiny-fleet")
    assert [d.id for d in cfg.duts] == ["unit-001", "unit-002", "unit-003", "unit-004"] and cfg.sessions == 5
    simulate_campaign("tiny-fleet", tmp_path / "raw" / "tf", jobs=2, progress=False)
    outcomes = label_sessions(expand_sessions([tmp_path / "raw" / "tf"]), LabelParams(), tmp_path / "labels",
                              jobs=2, progress=False)
    assert [o.error for o in outcomes if o.error] == [] and all(not o.labels.rejections for o in outcomes)
    labels = read_labels(tmp_path / "labels" / "tf")
    assert len(labels) == 20 and (labels["n_samples"] >= LabelParams().min_samples).all()
    assert set(labels["label_method"]) == {"level"}
    res = build_dataset(tmp_path / "labels" / "tf", tmp_path / "raw" / "tf", tmp_path / "ds", DatasetParams(),
                        truth_dir=tmp_path / "raw" / "tf" / "_truth", progress=False)
    assert (res.n_windows, res.n_recordings, res.n_shards) == (20, 20, 1)
    ds = load_dataset(res.path)
    assert ds.X.shape == (20, 3000, 3) and sorted(ds.meta["device"].unique()) == [d.id for d in cfg.duts]
    assert ds.info["dataset_info"]["label_fidelity"]  # against the simulator's truth, on the card
    assert np.array_equal(ds.y, labels.sort_values(["session", "recording", "device"])[
        ["bias_x", "bias_y", "bias_z"]].to_numpy())


def test_compact_duts_form() -> None:
    assert expand_duts([{"id": "a"}]) == [{"id": "a"}]
    assert expand_duts({"a": None, "b": {"up_axis": "-z"}}) == [{"id": "a"}, {"id": "b", "up_axis": "-z"}]
    assert expand_duts({"count": {"up_axis": "+x"}}) == [{"id": "count", "up_axis": "+x"}]  # a device
    assert expand_duts({"count": 3, "prefix": "dev-", "start": 0, "digits": 2, "up_axis": "-z"}) == [
        {"id": f"dev-0{k}", "up_axis": "-z"} for k in range(3)]
    assert [d["id"] for d in expand_duts({"count": 2})] == ["unit-001", "unit-002"]
    cfg = load_config_from(load_config("tiny-fleet"), {"duts": {"count": 2, "prefix": "b"}})
    assert [d.id for d in cfg.duts] == ["b001", "b002"]
    cfg = load_config("tiny-gravity-aligned", {"duts": {"count": 3, "up_axis": "-y"}})
    assert [(d.id, d.up_axis) for d in cfg.duts] == [(f"unit-00{k}", "-y") for k in (1, 2, 3)]


@pytest.mark.parametrize(("duts", "message"), [
    ({"count": 0}, "duts.count: expected an integer in 1..100000, found 0"),
    ({"count": 2.5}, "duts.count: expected an integer in 1..100000, found 2.5"),
    ({"count": 2, "digits": 0}, "duts.digits: expected an integer in 1..12, found 0"),
    ({"count": 2, "prefix": "a b"}, "duts.prefix: expected letters, digits, '.', '_' or '-' (device ids), "
                                    "found 'a b'"),
    ({"count": 2, "colour": "red"}, "duts.colour: expected one of count, prefix, start, digits, up_axis, "
                                    "reference_to_sensor, found an unknown key"),
    ({"count": 2, "up_axis": "up"}, "duts.unit-001.up_axis: expected one of +x -x +y -y +z -z, found 'up'"),
])
def test_bad_compact_duts_are_config_errors(duts: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_config("tiny-fleet", {"duts": duts})
    assert str(err.value).endswith(message), str(err.value)
