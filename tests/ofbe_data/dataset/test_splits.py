"""Cross-validation fold assignments: sizes, leakage guarantees, determinism, errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ofbe_data.core.errors import OfbeError
from ofbe_data.dataset.splits import (
    PROTOCOLS,
    SplitError,
    SplitParams,
    assign_folds,
    check_no_leak,
    fold_masks,
    fold_summary,
    grouped_folds,
    paper_gravity_folds,
    paper_rotated_folds,
    tilt_groups,
)
from tests.helpers.paths import ROOT

ID = ["session", "recording", "device"]


# --------------------------------------------------------------------------- synthetic campaigns


def gravity_from_roll_pitch(roll_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """u = [−sin θ, sin φ cos θ, cos φ cos θ] (orientation.roll_pitch's convention), (n, 3)."""
    r, p = np.radians(roll_deg), np.radians(pitch_deg)
    return np.stack([-np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)], axis=1)


def wrap180(deg: np.ndarray) -> np.ndarray:
    """Angles into (−180, 180]."""
    out = np.mod(np.asarray(deg, dtype=float) + 180.0, 360.0) - 180.0
    return np.where(out == -180.0, 180.0, out)


def frame(devices: list[str], roll_deg: np.ndarray, pitch_deg: np.ndarray, power_cycle: np.ndarray,
          campaign: str, per_session: int) -> pd.DataFrame:
    """One row per (recording, device); every device sees the same tilts (one rig)."""
    roll_deg = wrap180(roll_deg)
    u = gravity_from_roll_pitch(roll_deg, pitch_deg)
    n = len(roll_deg)
    parts = []
    for d in devices:
        parts.append(pd.DataFrame({
            "campaign": campaign,
            "session": [f"{campaign}-s{i // per_session}" for i in range(n)],
            "recording": [f"r{i:03d}" for i in range(n)],
            "device": d,
            "power_cycle": np.asarray(power_cycle, dtype=np.int64),
            "gravity_x": u[:, 0], "gravity_y": u[:, 1], "gravity_z": u[:, 2],
            "roll_deg": roll_deg, "pitch_deg": np.asarray(pitch_deg, dtype=float),
        }))
    return pd.concat(parts, ignore_index=True)


def gravity_campaign() -> pd.DataFrame:
    """4 devices × 100 level recordings, each in its own power cycle (ids repeat across devices)."""
    n = 100
    return frame(["dut-a", "dut-b", "dut-c", "dut-d"], np.zeros(n), np.zeros(n), np.arange(n),
                 "gravity", per_session=25)


def rotated_campaign() -> pd.DataFrame:
    """2 devices × 87 recordings at 87 distinct tilts; a power cycle every 3 recordings."""
    roll, pitch = np.meshgrid(np.arange(-168.0, 169.0, 12.0), [-30.0, 0.0, 30.0], indexing="ij")
    assert roll.size == 87
    return frame(["dut-a", "dut-b"], roll.ravel(), pitch.ravel(), np.arange(87) // 3, "rotated",
                 per_session=29)


def repeated_tilt_campaign(base_roll: np.ndarray | None = None, seed: int = 3) -> pd.DataFrame:
    """2 devices × 87 recordings: 29 tilts × 3 repeats with 0.01° noise on roll and pitch."""
    if base_roll is None:
        base_roll = np.arange(-168.0, 169.0, 12.0)
    rng = np.random.default_rng(seed)
    roll = np.repeat(base_roll, 3) + rng.uniform(-0.01, 0.01, 87)
    pitch = np.repeat(np.full(29, 20.0), 3) + rng.uniform(-0.01, 0.01, 87)
    return frame(["dut-a", "dut-b"], roll, pitch, np.arange(87) // 3, "repeat", per_session=29)


def wrap_campaign() -> pd.DataFrame:
    """Like repeated_tilt_campaign, but one tilt sits at roll ±180° and its repeats straddle the wrap."""
    base = 180.0 - 12.0 * np.arange(29)  # 180, 168, …, −156
    df = repeated_tilt_campaign(base)
    straddle = np.array([179.995, -179.995, 180.0])  # same tilt, roll values 360° apart
    for d in df["device"].unique():
        idx = df.index[(df["device"] == d) & df["recording"].isin(["r000", "r001", "r002"])]
        u = gravity_from_roll_pitch(straddle, np.full(3, 20.0))
        df.loc[idx, ["gravity_x", "gravity_y", "gravity_z"]] = u
        df.loc[idx, "roll_deg"] = straddle
        df.loc[idx, "pitch_deg"] = 20.0
    return df


def per_device_fold_sizes(df: pd.DataFrame, folds: np.ndarray, n_folds: int = 5) -> dict[str, list[int]]:
    return {d: np.bincount(folds[(df["device"] == d).to_numpy()] + 1, minlength=n_folds + 1).tolist()
            for d in sorted(df["device"].unique())}  # index 0 counts the −1s


# --------------------------------------------------------------------------- independent checks


def assert_no_tilt_leak(df: pd.DataFrame, folds: np.ndarray, tol_deg: float, n_folds: int = 5) -> None:
    """Brute force: every test/train pair of one device is at least tol_deg apart (arccos of dot)."""
    u = df[["gravity_x", "gravity_y", "gravity_z"]].to_numpy()
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    for d in df["device"].unique():
        mine = (df["device"] == d).to_numpy()
        for k in range(n_folds):
            test, train = u[mine & (folds == k)], u[mine & (folds != k)]
            angles = np.degrees(np.arccos(np.clip(test @ train.T, -1.0, 1.0)))
            assert angles.min() >= tol_deg, (d, k, angles.min())


def assert_no_cycle_leak(df: pd.DataFrame, folds: np.ndarray, n_folds: int = 5) -> None:
    """Bias instances (device, power_cycle) of the test and training sets are disjoint."""
    inst = list(zip(df["device"], df["power_cycle"], strict=True))
    for k in range(n_folds):
        test = {i for i, f in zip(inst, folds, strict=True) if f == k}
        train = {i for i, f in zip(inst, folds, strict=True) if f != k}
        assert not test & train, (k, sorted(test & train)[:3])


def assert_every_device_in_every_fold(df: pd.DataFrame, folds: np.ndarray, n_folds: int = 5) -> None:
    for k in range(n_folds):
        assert set(df.loc[folds == k, "device"]) == set(df["device"]), k


# --------------------------------------------------------------------------- paper-gravity


def test_paper_gravity_tests_each_recording_once_in_equal_parts():
    df = gravity_campaign()
    folds = assign_folds(df, "paper-gravity", SplitParams(seed=7))
    assert isinstance(folds, np.ndarray) and folds.dtype == np.int64 and folds.shape == (400,)
    for d, sizes in per_device_fold_sizes(df, folds).items():
        assert sizes == [0, 20, 20, 20, 20, 20], d
    assert_every_device_in_every_fold(df, folds)
    summary = fold_summary(df, folds)
    assert list(summary.columns) == ["fold", "device", "n_test", "n_train"]
    assert len(summary) == 5 * 4
    assert (summary["n_test"] == 20).all() and (summary["n_train"] == 80).all()


def test_paper_gravity_sizes_differ_by_at_most_one():
    df = gravity_campaign().iloc[:103]  # dut-a: 100, dut-b: 3 → too few; use 2 folds instead
    folds = paper_gravity_folds(df, SplitParams(n_folds=2))
    assert per_device_fold_sizes(df, folds, 2) == {"dut-a": [0, 50, 50], "dut-b": [0, 2, 1]}
    df = gravity_campaign().iloc[:97]
    sizes = np.bincount(paper_gravity_folds(df, SplitParams(seed=1)))
    assert sorted(sizes.tolist()) == [19, 19, 19, 20, 20]


def test_paper_gravity_leaks_power_cycles_as_documented():
    """The paper's protocol splits bias instances across folds; grouped does not."""
    df = rotated_campaign()
    folds = assign_folds(df, "paper-gravity")
    with pytest.raises(AssertionError):
        assert_no_cycle_leak(df, folds)
    with pytest.raises(SplitError, match="bias instance"):
        check_no_leak(df, folds, "grouped")


# --------------------------------------------------------------------------- paper-rotated


def test_paper_rotated_distinct_tilts_gives_nine_per_fold():
    df = rotated_campaign()
    folds = assign_folds(df, "paper-rotated")
    for d, sizes in per_device_fold_sizes(df, folds).items():
        assert sizes == [42, 9, 9, 9, 9, 9], d
    assert_every_device_in_every_fold(df, folds)
    assert_no_tilt_leak(df, folds, 0.5)
    summary = fold_summary(df, folds)
    assert (summary["n_test"] == 9).all() and (summary["n_train"] == 78).all()


def test_paper_rotated_repeated_tilts_keeps_groups_whole():
    df = repeated_tilt_campaign()
    folds = assign_folds(df, "paper-rotated", SplitParams(seed=11))
    for d, sizes in per_device_fold_sizes(df, folds).items():
        assert sizes == [42, 9, 9, 9, 9, 9], d
    # every repeat of a tilt (rows 3i, 3i+1, 3i+2 of a device) has one fold value
    for d in df["device"].unique():
        f = folds[(df["device"] == d).to_numpy()].reshape(29, 3)
        assert (f == f[:, :1]).all(), d
    check_no_leak(df, folds, "paper-rotated", SplitParams(seed=11))
    assert_no_tilt_leak(df, folds, 0.5)


def test_paper_rotated_handles_roll_wrap_at_180():
    df = wrap_campaign()
    # roll differences say these are 360° apart; the gravity vectors are 0.01° apart
    first = df[(df["device"] == "dut-a") & df["recording"].isin(["r000", "r001", "r002"])]
    assert np.ptp(first["roll_deg"]) > 359.0
    labels = tilt_groups(first[["gravity_x", "gravity_y", "gravity_z"]].to_numpy(), 0.5)
    assert labels.tolist() == [0, 0, 0]
    for seed in range(6):
        params = SplitParams(seed=seed)
        folds = assign_folds(df, "paper-rotated", params)
        for d in df["device"].unique():
            f = folds[(df["device"] == d).to_numpy()].reshape(29, 3)
            assert (f == f[:, :1]).all(), (seed, d)
        assert all(s == [42, 9, 9, 9, 9, 9] for s in per_device_fold_sizes(df, folds).values())
        assert_no_tilt_leak(df, folds, 0.5)


def test_paper_rotated_ignores_roll_pitch_columns():
    df = rotated_campaign()
    expected = paper_rotated_folds(df)
    scrambled = df.assign(roll_deg=0.0, pitch_deg=0.0)
    np.testing.assert_array_equal(paper_rotated_folds(scrambled), expected)
    np.testing.assert_array_equal(paper_rotated_folds(df.drop(columns=["roll_deg", "pitch_deg"])), expected)


def test_tilt_groups_single_linkage_and_strict_tolerance():
    # a chain of 0.3° steps links 0° … 0.9° (single linkage) though the ends are 0.9° apart
    roll = np.array([0.0, 0.3, 0.6, 0.9, 5.0, 5.51, 10.0, 10.49])
    labels = tilt_groups(gravity_from_roll_pitch(roll, np.zeros(8)), 0.5)
    assert labels.tolist() == [0, 0, 0, 0, 1, 2, 3, 3]  # 0.51° apart: not linked; 0.49°: linked
    # gravity need not be normalised and labels follow first occurrence
    u = gravity_from_roll_pitch(np.array([90.0, 0.0, 0.1]), np.zeros(3)) * 9.81
    assert tilt_groups(u, 0.5).tolist() == [0, 1, 1]
    assert tilt_groups(np.zeros((0, 3)), 0.5).tolist() == []


def test_paper_rotated_partial_folds_when_groups_do_not_add_up():
    # 29 tilts × 3 repeats with test_per_fold = 10: whole groups of 3 fill 9 of the 10 places
    df = repeated_tilt_campaign()
    params = SplitParams(test_per_fold=10)
    folds = assign_folds(df, "paper-rotated", params)
    for sizes in per_device_fold_sizes(df, folds).values():
        assert sizes == [42, 9, 9, 9, 9, 9]


# --------------------------------------------------------------------------- grouped


def test_grouped_on_rotated_campaign_balances_power_cycles():
    df = rotated_campaign()
    folds = assign_folds(df, "grouped", SplitParams(seed=5))
    for d, sizes in per_device_fold_sizes(df, folds).items():
        assert sizes[0] == 0 and sorted(sizes[1:]) == [15, 18, 18, 18, 18], d
    assert_no_cycle_leak(df, folds)
    assert_every_device_in_every_fold(df, folds)


def test_grouped_on_gravity_campaign_and_uneven_cycles():
    df = gravity_campaign()
    folds = grouped_folds(df)
    assert all(s == [0, 20, 20, 20, 20, 20] for s in per_device_fold_sizes(df, folds).values())
    # uneven cycles: sizes 7, 5, 4, 3, 3, 2, 1 over 3 folds → greedy largest-first gives 9/8/8
    cycles = np.repeat(np.arange(7), [7, 5, 4, 3, 3, 2, 1])
    df = frame(["x"], np.zeros(25), np.zeros(25), cycles, "uneven", per_session=25)
    folds = assign_folds(df, "grouped", SplitParams(n_folds=3))
    assert sorted(np.bincount(folds).tolist()) == [8, 8, 9]
    assert_no_cycle_leak(df, folds, 3)


@settings(max_examples=40, deadline=None)
@given(n_folds=st.integers(2, 6), seed=st.integers(0, 2**31), data=st.data())
def test_grouped_never_leaks(n_folds, seed, data):
    n_devices = data.draw(st.integers(1, 4))
    parts = []
    for d in range(n_devices):
        n_cycles = data.draw(st.integers(n_folds, n_folds + 8))
        per_cycle = data.draw(st.lists(st.integers(1, 5), min_size=n_cycles, max_size=n_cycles))
        ids = data.draw(st.lists(st.integers(0, 50), min_size=n_cycles, max_size=n_cycles, unique=True))
        cycles = np.repeat(ids, per_cycle)
        parts.append(frame([f"dev{d}"], np.zeros(len(cycles)), np.zeros(len(cycles)), cycles, "h", 7))
    df = pd.concat(parts, ignore_index=True)
    params = SplitParams(n_folds=n_folds, seed=seed)
    folds = assign_folds(df, "grouped", params)
    assert folds.dtype == np.int64 and ((folds >= 0) & (folds < n_folds)).all()
    assert_no_cycle_leak(df, folds, n_folds)
    assert_every_device_in_every_fold(df, folds, n_folds)
    # balance: no fold exceeds the lightest one by more than the largest power cycle
    for d in df["device"].unique():
        mine = (df["device"] == d).to_numpy()
        loads = np.bincount(folds[mine], minlength=n_folds)
        assert loads.max() - loads.min() <= df[mine].groupby("power_cycle").size().max()


# --------------------------------------------------------------------------- check_no_leak


def test_check_no_leak_catches_a_split_tilt_group():
    df = repeated_tilt_campaign()
    folds = paper_rotated_folds(df)
    row = int(np.flatnonzero(folds == 2)[0])  # move one repeat of a test tilt to training
    leaky = folds.copy()
    leaky[row] = -1
    rid = "/".join(df.loc[row, ID])
    with pytest.raises(SplitError, match=r"paper-rotated: fold 2: .*tilt group.*") as err:
        check_no_leak(df, leaky, "paper-rotated")
    assert rid in str(err.value)
    with pytest.raises(AssertionError):
        assert_no_tilt_leak(df, leaky, 0.5)


def test_check_no_leak_catches_a_split_power_cycle():
    df = rotated_campaign()
    folds = grouped_folds(df)
    row = int(np.flatnonzero(folds == 3)[0])
    leaky = folds.copy()
    leaky[row] = 1 if folds[row] != 1 else 0
    with pytest.raises(SplitError, match=r"grouped: fold \d: .*bias instance") as err:
        check_no_leak(df, leaky, "grouped")
    assert "/".join(df.loc[row, ID]) in str(err.value)
    with pytest.raises(AssertionError):
        assert_no_cycle_leak(df, leaky)


def test_check_no_leak_other_guarantees():
    df = gravity_campaign()
    folds = paper_gravity_folds(df)
    bad = folds.copy()
    bad[0] = -1
    with pytest.raises(SplitError, match="tested once"):
        check_no_leak(df, bad, "paper-gravity")
    bad = folds.copy()
    bad[(df["device"] == "dut-c").to_numpy() & (folds == 4)] = 0
    with pytest.raises(SplitError, match="fold 4: device.s. dut-c have no test recording"):
        check_no_leak(df, bad, "paper-gravity")
    with pytest.raises(SplitError, match=r"expected values in -1..4, found \[5\]"):
        check_no_leak(df, np.where(folds == 4, 5, folds), "paper-gravity")
    with pytest.raises(SplitError, match=r"expected shape \(400,\)"):
        check_no_leak(df, folds[:-1], "paper-gravity")
    rot = rotated_campaign()
    too_many = paper_rotated_folds(rot)
    too_many[too_many == -1] = 0
    with pytest.raises(SplitError, match="fold 0: device dut-a has 51 test recordings, more than"):
        check_no_leak(rot, too_many, "paper-rotated")


# --------------------------------------------------------------------------- determinism


CAMPAIGNS = {"paper-gravity": gravity_campaign, "paper-rotated": repeated_tilt_campaign,
             "grouped": rotated_campaign}


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_deterministic_and_independent_of_row_order(protocol):
    df = CAMPAIGNS[protocol]()
    folds = assign_folds(df, protocol, SplitParams(seed=42))
    np.testing.assert_array_equal(assign_folds(df, protocol, SplitParams(seed=42)), folds)

    shuffled = df.sample(frac=1.0, random_state=123)
    shuffled.index = np.arange(100_000, 100_000 + len(df))[::-1]  # unrelated index
    again = assign_folds(shuffled, protocol, SplitParams(seed=42))
    by_id = pd.Series(folds, index=pd.MultiIndex.from_frame(df[ID]))
    expected = by_id.loc[pd.MultiIndex.from_frame(shuffled[ID])].to_numpy()
    np.testing.assert_array_equal(again, expected)

    other = assign_folds(df, protocol, SplitParams(seed=43))
    assert (other != folds).any()


def test_devices_get_independent_shuffles():
    df = gravity_campaign()
    folds = paper_gravity_folds(df)
    a, b = (folds[(df["device"] == d).to_numpy()] for d in ("dut-a", "dut-b"))
    assert (a != b).any()


def test_independent_of_python_hash_seed():
    code = ("import sys; sys.path.insert(0, sys.argv[1]); sys.path.insert(0, sys.argv[2]);"
            "from test_splits import rotated_campaign; from ofbe_data.dataset.splits import assign_folds;"
            "print(''.join(str(f) for f in assign_folds(rotated_campaign(), 'grouped')))")
    here = Path(__file__).resolve().parent
    out = subprocess.run([sys.executable, "-c", code, str(ROOT), str(here)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONHASHSEED": "12345"}, check=True).stdout.strip()
    assert out == "".join(str(f) for f in assign_folds(rotated_campaign(), "grouped"))


# --------------------------------------------------------------------------- masks and errors


def test_fold_masks_train_includes_never_tested():
    folds = np.array([0, 1, -1, 2, 1, -1])
    train, test = fold_masks(folds, 1)
    assert test.tolist() == [False, True, False, False, True, False]
    assert train.tolist() == [True, False, True, True, False, True]
    with pytest.raises(SplitError, match="k: expected a fold index >= 0"):
        fold_masks(folds, -1)


def test_unknown_protocol_lists_the_valid_ones():
    with pytest.raises(SplitError, match="paper-gravity, paper-rotated, grouped, found 'leave-one-out'"):
        assign_folds(gravity_campaign(), "leave-one-out")
    assert issubclass(SplitError, OfbeError)


@pytest.mark.parametrize(("protocol", "drop", "named"), [
    ("paper-gravity", ["session"], "session"),
    ("paper-rotated", ["gravity_x", "gravity_z"], "gravity_x, gravity_z"),
    ("grouped", ["power_cycle", "device"], "device, power_cycle"),
])
def test_missing_columns_are_named(protocol, drop, named):
    with pytest.raises(SplitError, match=f"missing column\\(s\\) {named}"):
        assign_folds(rotated_campaign().drop(columns=drop), protocol)


def test_too_few_recordings_or_cycles():
    df = rotated_campaign()
    small = df[df["recording"] < "r044"]  # 44 recordings per device
    with pytest.raises(SplitError, match=r"device dut-a has 44 recordings, needs at least n_folds \* "
                                         r"test_per_fold = 5 \* 9 = 45"):
        assign_folds(small, "paper-rotated")
    few = df[df["power_cycle"] < 4]
    with pytest.raises(SplitError, match="device dut-a has 4 power cycle.s., needs at least n_folds = 5"):
        assign_folds(few, "grouped")
    with pytest.raises(SplitError, match="paper-gravity: device dut-a has 3 recordings"):
        assign_folds(df[df["recording"] < "r003"], "paper-gravity")
    # all recordings at one tilt: no group fits into a fold
    with pytest.raises(SplitError, match="get no test recording.*largest group 100"):
        assign_folds(gravity_campaign(), "paper-rotated")


def test_bad_inputs():
    df = rotated_campaign()
    dup = pd.concat([df, df.iloc[[5]]], ignore_index=True)
    with pytest.raises(SplitError, match=r"must be unique, found duplicates \[rotated-s0/r005/dut-a\]"):
        assign_folds(dup, "grouped")
    zero = df.copy()
    zero.loc[3, ["gravity_x", "gravity_y", "gravity_z"]] = 0.0
    with pytest.raises(SplitError, match=r"finite non-zero directions.*rotated-s0/r003/dut-a"):
        assign_folds(zero, "paper-rotated")
    with pytest.raises(SplitError, match="power_cycle: expected an integer column, found dtype float64"):
        assign_folds(df.astype({"power_cycle": "float64"}), "grouped")


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"n_folds": 1}, "n_folds: expected an integer >= 2, found 1"),
    ({"n_folds": 2.0}, "n_folds: expected an integer >= 2"),
    ({"seed": "0"}, "seed: expected an integer"),
    ({"test_per_fold": 0}, "test_per_fold: expected an integer >= 1"),
    ({"tilt_tolerance_deg": 0.0}, r"tilt_tolerance_deg: expected a number in \(0, 180\)"),
    ({"tilt_tolerance_deg": float("nan")}, "tilt_tolerance_deg"),
])
def test_invalid_params(kwargs, message):
    with pytest.raises(SplitError, match=message):
        SplitParams(**kwargs)
