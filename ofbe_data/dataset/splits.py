"""Cross-validation protocols (methods.md §Protocols) as fold assignments per recording.

A fold assignment gives, for each labelled (recording, DUT device) row, the index
``0 … n_folds − 1`` of the one fold in which that recording is a *test* recording, or ``−1``
when it is only ever used for training. The training set of fold ``k`` is every recording
whose fold is not ``k`` (``−1`` included). The dataset stores these as ``fold_<protocol>``
columns (products.md §Dataset).

Protocols
---------
``paper-gravity``
    Per device, the recordings are shuffled and dealt into ``n_folds`` test parts whose sizes
    differ by at most one: every recording is tested exactly once, each test fold holds about
    1/n_folds of each device's recordings and every device appears in every test fold.
    **Known leak (the paper's protocol, kept on purpose):** recordings made within one power
    cycle share a bias instance, and they may fall on both sides of a fold, so a model can be
    tested on a bias it was trained on. ``grouped`` is the leakage-free alternative.
``paper-rotated``
    Per device separately, recordings are grouped by tilt (two recordings share a tilt when
    the angle between their gravity directions is below ``tilt_tolerance_deg``; groups are
    the connected components of that relation, so the relation is closed transitively). Tilt
    groups are shuffled and whole groups fill the folds until each has ``test_per_fold`` test
    recordings; the rest are training-only (``−1``). No test recording of fold ``k`` shares a
    tilt group with a training recording of fold ``k``. Tilts are compared on the unit
    gravity vectors, never on roll/pitch differences (those wrap at ±180°). Tilts are *not*
    compared across devices: the protocol assumes one model per device.
``grouped``
    Beyond the paper. Per device, the power cycles (bias instances ``(device, power_cycle)``)
    are shuffled and dealt into ``n_folds`` parts balanced by number of recordings; every
    recording takes its power cycle's fold. No bias instance is in both the test and the
    training set of a fold.

Determinism: the row identity is ``(session, recording, device)``; rows are processed in
the order of their identities (as strings), and each device's random generator is seeded by
a SHA-256 digest of ``(seed, protocol, device)``. The assignment therefore depends only on
the set of rows and the parameters, never on the input row order or on ``PYTHONHASHSEED``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ofbe_data.core.errors import OfbeError

PROTOCOLS = ("paper-gravity", "paper-rotated", "grouped")
"""The valid protocol names, in the order the benchmark reports them."""

IDENTITY_COLUMNS = ("session", "recording", "device")
"""Columns that identify one row (one recording of one DUT device)."""

GRAVITY_COLUMNS = ("gravity_x", "gravity_y", "gravity_z")
"""Unit specific-force direction in the sensor frame."""

_REQUIRED: dict[str, tuple[str, ...]] = {
    "paper-gravity": IDENTITY_COLUMNS,
    "paper-rotated": IDENTITY_COLUMNS + GRAVITY_COLUMNS,
    "grouped": IDENTITY_COLUMNS + ("power_cycle",),
}

_MAX_LISTED = 10
"""How many offending recordings an error message lists at most."""


class SplitError(OfbeError):
    """A fold assignment cannot be made, or an assignment breaks its protocol's guarantee."""


@dataclass(frozen=True)
class SplitParams:
    """Parameters of the cross-validation protocols.

    Attributes
    ----------
    n_folds
        Number of folds, at least 2.
    seed
        Seed of the shuffles; combined with the protocol and the device name.
    test_per_fold
        ``paper-rotated`` only: test recordings per device per fold (the paper's 9).
    tilt_tolerance_deg
        ``paper-rotated`` only: two recordings have the same tilt when the angle between
        their gravity directions is below this, degrees.
    """

    n_folds: int = 5
    seed: int = 0
    test_per_fold: int = 9
    tilt_tolerance_deg: float = 0.5

    def __post_init__(self) -> None:
        if isinstance(self.n_folds, bool) or not isinstance(self.n_folds, int | np.integer) \
                or self.n_folds < 2:
            raise SplitError(f"n_folds: expected an integer >= 2, found {self.n_folds!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer):
            raise SplitError(f"seed: expected an integer, found {self.seed!r}")
        if isinstance(self.test_per_fold, bool) or not isinstance(self.test_per_fold, int | np.integer) \
                or self.test_per_fold < 1:
            raise SplitError(f"test_per_fold: expected an integer >= 1, found {self.test_per_fold!r}")
        tol = self.tilt_tolerance_deg
        if isinstance(tol, bool) or not isinstance(tol, int | float | np.floating | np.integer) \
                or not (np.isfinite(tol) and 0.0 < tol < 180.0):
            raise SplitError(f"tilt_tolerance_deg: expected a number in (0, 180) degrees, found {tol!r}")


# --------------------------------------------------------------------------- helpers


def _check_protocol(protocol: str) -> None:
    if protocol not in PROTOCOLS:
        raise SplitError(f"protocol: expected one of {', '.join(PROTOCOLS)}, found {protocol!r}")


def _check_columns(recordings: pd.DataFrame, columns: Sequence[str]) -> None:
    missing = [c for c in columns if c not in recordings.columns]
    if missing:
        raise SplitError(f"recordings: missing column(s) {', '.join(missing)}")


def _keys(recordings: pd.DataFrame) -> pd.DataFrame:
    """The identity columns as strings, positional index; raises on duplicate identities."""
    keys = pd.DataFrame({c: recordings[c].astype(str).to_numpy(dtype=object) for c in IDENTITY_COLUMNS})
    dup = keys.duplicated(keep=False).to_numpy()
    if dup.any():
        raise SplitError(f"recordings: (session, recording, device) must be unique, found duplicates "
                         f"{_describe(keys, np.flatnonzero(dup))}")
    return keys


def _sorted_order(keys: pd.DataFrame) -> np.ndarray:
    """Row positions sorted by identity, shape (n,), int64."""
    return keys.sort_values(list(IDENTITY_COLUMNS), kind="mergesort").index.to_numpy(dtype=np.int64)


def _describe(keys: pd.DataFrame, rows: np.ndarray) -> str:
    """Human-readable list of at most ``_MAX_LISTED`` distinct row identities, sorted."""
    sub = keys.iloc[np.asarray(rows, dtype=np.int64)]
    ids = sorted(set((sub["session"] + "/" + sub["recording"] + "/" + sub["device"]).tolist()))
    more = f" and {len(ids) - _MAX_LISTED} more" if len(ids) > _MAX_LISTED else ""
    return "[" + ", ".join(ids[:_MAX_LISTED]) + "]" + more


def _device_rows(keys: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """Per device (sorted by name): its row positions in identity order."""
    order = _sorted_order(keys)
    devices = keys["device"].to_numpy(dtype=object)[order]
    return [(str(d), order[devices == d]) for d in sorted(set(devices.tolist()))]


def device_rng(seed: int, protocol: str, device: str) -> np.random.Generator:
    """The generator of one device's shuffle, seeded stably from (seed, protocol, device).

    Parameters
    ----------
    seed
        ``SplitParams.seed``.
    protocol, device
        Names; the seed is the first 8 bytes of ``sha256(f"{seed}|{protocol}|{device}")``.

    Returns
    -------
    numpy.random.Generator
    """
    digest = hashlib.sha256(f"{int(seed)}|{protocol}|{device}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


def _unit_gravity(recordings: pd.DataFrame, keys: pd.DataFrame) -> np.ndarray:
    """Gravity directions normalised to unit length, shape (n, 3)."""
    g = recordings[list(GRAVITY_COLUMNS)].to_numpy(dtype=np.float64)
    norm = np.linalg.norm(g, axis=1)
    bad = ~(np.isfinite(norm) & (norm > 0.0))
    if bad.any():
        raise SplitError(f"gravity_x/y/z: expected finite non-zero directions, found invalid ones in "
                         f"{_describe(keys, np.flatnonzero(bad))}")
    return g / norm[:, None]


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors row by row, degrees; accurate for small angles too."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


def tilt_groups(gravity: np.ndarray, tolerance_deg: float) -> np.ndarray:
    """Group directions by tilt: connected components of "angle below ``tolerance_deg``".

    Parameters
    ----------
    gravity
        (n, 3) specific-force directions, sensor frame (any non-zero length; normalised here).
    tolerance_deg
        Two directions are linked when the angle between them is strictly below this, degrees.

    Returns
    -------
    ndarray, shape (n,), int64
        Group label per row, numbered ``0, 1, …`` in the order of each group's first row.
    """
    u = np.asarray(gravity, dtype=np.float64).reshape(-1, 3)
    norm = np.linalg.norm(u, axis=1)
    if not (np.isfinite(norm) & (norm > 0.0)).all():
        raise SplitError("gravity: expected finite non-zero directions, found zero or non-finite rows "
                         f"{np.flatnonzero(~(np.isfinite(norm) & (norm > 0.0))).tolist()}")
    u = u / norm[:, None]
    n = len(u)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    # chord length of the tolerance angle, slightly widened; the exact test is on the angle
    chord = 2.0 * np.sin(np.radians(tolerance_deg) / 2.0) * (1.0 + 1e-9) + 1e-12
    pairs = cKDTree(u).query_pairs(chord, output_type="ndarray")
    if len(pairs):
        pairs = pairs[_angle_deg(u[pairs[:, 0]], u[pairs[:, 1]]) < tolerance_deg]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    # renumber by first occurrence so the labels depend only on the row order
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inverse.reshape(-1)]


def _fold_values(folds: np.ndarray, n_rows: int, n_folds: int) -> np.ndarray:
    folds = np.asarray(folds)
    if folds.shape != (n_rows,):
        raise SplitError(f"folds: expected shape ({n_rows},), found {folds.shape}")
    if not np.issubdtype(folds.dtype, np.integer):
        raise SplitError(f"folds: expected integers, found dtype {folds.dtype}")
    bad = (folds < -1) | (folds >= n_folds)
    if bad.any():
        found = sorted(set(folds[bad].tolist()))
        raise SplitError(f"folds: expected values in -1..{n_folds - 1}, found {found}")
    return folds.astype(np.int64)


# --------------------------------------------------------------------------- protocols


def paper_gravity_folds(recordings: pd.DataFrame, params: SplitParams | None = None) -> np.ndarray:
    """Fold assignment of the ``paper-gravity`` protocol.

    Parameters
    ----------
    recordings
        One row per (recording, device); needs ``session``, ``recording``, ``device``.
    params
        ``n_folds`` and ``seed`` are used; defaults to ``SplitParams()``.

    Returns
    -------
    ndarray, shape (n,), int64
        Test fold of each row, in input row order; never ``−1``.

    Raises
    ------
    SplitError
        Missing columns, duplicate identities, or a device with fewer recordings than folds.
    """
    params = SplitParams() if params is None else params
    _check_columns(recordings, _REQUIRED["paper-gravity"])
    keys = _keys(recordings)
    folds = np.full(len(keys), -1, dtype=np.int64)
    for device, rows in _device_rows(keys):
        if len(rows) < params.n_folds:
            raise SplitError(f"paper-gravity: device {device} has {len(rows)} recordings, "
                             f"needs at least n_folds = {params.n_folds}")
        perm = device_rng(params.seed, "paper-gravity", device).permutation(len(rows))
        folds[rows[perm]] = np.arange(len(rows)) % params.n_folds
    return folds


def paper_rotated_folds(recordings: pd.DataFrame, params: SplitParams | None = None) -> np.ndarray:
    """Fold assignment of the ``paper-rotated`` protocol (unseen tilts, per device).

    Tilt groups (see :func:`tilt_groups`) are shuffled; each group goes whole into the first
    fold, from the first one not yet full, that still has room for it, until every fold has
    ``test_per_fold`` test recordings. Groups that fit nowhere are training-only (``−1``).
    When the groups' sizes do not add up exactly, a fold can end with fewer than
    ``test_per_fold`` test recordings (never more); it is never empty.

    Parameters
    ----------
    recordings
        One row per (recording, device); needs the identity and ``gravity_x/y/z``.
    params
        ``n_folds``, ``seed``, ``test_per_fold``, ``tilt_tolerance_deg``; defaults to
        ``SplitParams()``.

    Returns
    -------
    ndarray, shape (n,), int64
        Test fold of each row or ``−1``, in input row order.

    Raises
    ------
    SplitError
        Missing columns, duplicate identities, invalid gravity directions, a device with
        fewer than ``n_folds · test_per_fold`` recordings, or a fold left without any test
        recording of a device (tilt groups too large).
    """
    params = SplitParams() if params is None else params
    _check_columns(recordings, _REQUIRED["paper-rotated"])
    keys = _keys(recordings)
    u = _unit_gravity(recordings, keys)
    folds = np.full(len(keys), -1, dtype=np.int64)
    needed = params.n_folds * params.test_per_fold
    for device, rows in _device_rows(keys):
        if len(rows) < needed:
            raise SplitError(f"paper-rotated: device {device} has {len(rows)} recordings, needs at least "
                             f"n_folds * test_per_fold = {params.n_folds} * {params.test_per_fold} "
                             f"= {needed}")
        groups = tilt_groups(u[rows], params.tilt_tolerance_deg)
        sizes = np.bincount(groups)
        counts = np.zeros(params.n_folds, dtype=np.int64)
        group_fold = np.full(len(sizes), -1, dtype=np.int64)
        current = 0
        for g in device_rng(params.seed, "paper-rotated", device).permutation(len(sizes)):
            while current < params.n_folds and counts[current] >= params.test_per_fold:
                current += 1
            if current == params.n_folds:
                break
            for k in range(current, params.n_folds):
                if counts[k] + sizes[g] <= params.test_per_fold:
                    group_fold[g] = k
                    counts[k] += sizes[g]
                    break
        if (counts == 0).any():
            empty = np.flatnonzero(counts == 0).tolist()
            raise SplitError(f"paper-rotated: device {device}: fold(s) {empty} get no test recording; "
                             f"every tilt group left is larger than test_per_fold = {params.test_per_fold} "
                             f"(largest group {int(sizes.max())} recordings)")
        folds[rows] = group_fold[groups]
    return folds


def grouped_folds(recordings: pd.DataFrame, params: SplitParams | None = None) -> np.ndarray:
    """Fold assignment of the ``grouped`` protocol (folds by power cycle, per device).

    Each device's power cycles are shuffled, then stably sorted by number of recordings
    (largest first) and each is given to the fold with the fewest recordings so far (lowest
    index on ties). Every recording takes its power cycle's fold.

    Parameters
    ----------
    recordings
        One row per (recording, device); needs the identity and ``power_cycle`` (integer).
    params
        ``n_folds`` and ``seed``; defaults to ``SplitParams()``.

    Returns
    -------
    ndarray, shape (n,), int64
        Test fold of each row, in input row order; never ``−1``.

    Raises
    ------
    SplitError
        Missing columns, duplicate identities, non-integer power cycles, or a device with
        fewer power cycles than folds.
    """
    params = SplitParams() if params is None else params
    _check_columns(recordings, _REQUIRED["grouped"])
    keys = _keys(recordings)
    cycles = _power_cycles(recordings, keys)
    folds = np.full(len(keys), -1, dtype=np.int64)
    for device, rows in _device_rows(keys):
        ids, inverse, sizes = np.unique(cycles[rows], return_inverse=True, return_counts=True)
        if len(ids) < params.n_folds:
            raise SplitError(f"grouped: device {device} has {len(ids)} power cycle(s), "
                             f"needs at least n_folds = {params.n_folds}")
        perm = device_rng(params.seed, "grouped", device).permutation(len(ids))
        perm = perm[np.argsort(-sizes[perm], kind="stable")]
        load = np.zeros(params.n_folds, dtype=np.int64)
        cycle_fold = np.empty(len(ids), dtype=np.int64)
        for c in perm:
            k = int(np.argmin(load))  # first minimum: ties go to the lowest fold index
            cycle_fold[c] = k
            load[k] += sizes[c]
        folds[rows] = cycle_fold[inverse.reshape(-1)]
    return folds


def _power_cycles(recordings: pd.DataFrame, keys: pd.DataFrame) -> np.ndarray:
    col = recordings["power_cycle"]
    if not pd.api.types.is_integer_dtype(col.dtype):
        raise SplitError(f"power_cycle: expected an integer column, found dtype {col.dtype}")
    if col.isna().any():
        raise SplitError(f"power_cycle: expected no missing values, found them in "
                         f"{_describe(keys, np.flatnonzero(col.isna().to_numpy()))}")
    return col.to_numpy(dtype=np.int64)


_BUILDERS = {
    "paper-gravity": paper_gravity_folds,
    "paper-rotated": paper_rotated_folds,
    "grouped": grouped_folds,
}


def assign_folds(recordings: pd.DataFrame, protocol: str, params: SplitParams | None = None) -> np.ndarray:
    """Fold assignment of ``protocol``, self-checked with :func:`check_no_leak`.

    Parameters
    ----------
    recordings
        One row per (recording, device); see the protocol functions for the columns.
    protocol
        One of :data:`PROTOCOLS`.
    params
        Defaults to ``SplitParams()``.

    Returns
    -------
    ndarray, shape (n,), int64
        Test fold index ``0 … n_folds − 1`` of each row, or ``−1`` (training only), aligned
        with the input rows by position.
    """
    _check_protocol(protocol)
    params = SplitParams() if params is None else params
    folds = _BUILDERS[protocol](recordings, params)
    check_no_leak(recordings, folds, protocol, params)
    return folds


def fold_masks(folds: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Training and test masks of fold ``k``.

    Parameters
    ----------
    folds
        (n,) fold assignment.
    k
        Fold index, ``>= 0``.

    Returns
    -------
    train, test
        (n,) boolean masks: ``folds != k`` and ``folds == k``.
    """
    if isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 0:
        raise SplitError(f"k: expected a fold index >= 0, found {k!r}")
    folds = np.asarray(folds)
    test = folds == k
    return ~test, test


# --------------------------------------------------------------------------- checks


def check_no_leak(recordings: pd.DataFrame, folds: np.ndarray, protocol: str,
                  params: SplitParams | None = None) -> None:
    """Raise :class:`SplitError` when ``folds`` breaks the guarantee of ``protocol``.

    Checked for every protocol: shape, integer values in ``−1 … n_folds − 1`` and every
    device present in every test fold. Then

    - ``paper-gravity``: every recording is tested exactly once (no ``−1``) and each device's
      test parts differ in size by at most one (the power-cycle leak is the protocol's own);
    - ``paper-rotated``: no test recording of fold k shares a tilt group (same device) with a
      training recording of fold k, and no fold has more than ``test_per_fold`` test
      recordings of a device;
    - ``grouped``: no bias instance ``(device, power_cycle)`` has recordings both in the test
      set and in the training set of a fold.

    Parameters
    ----------
    recordings
        The frame the assignment was made for.
    folds
        (n,) assignment, aligned with ``recordings`` by position.
    protocol
        One of :data:`PROTOCOLS`.
    params
        Defaults to ``SplitParams()``.

    Raises
    ------
    SplitError
        Naming the protocol, the fold and (some of) the offending recordings.
    """
    _check_protocol(protocol)
    params = SplitParams() if params is None else params
    _check_columns(recordings, _REQUIRED[protocol])
    keys = _keys(recordings)
    folds = _fold_values(folds, len(keys), params.n_folds)
    per_device = _device_rows(keys)

    for k in range(params.n_folds):
        absent = [d for d, rows in per_device if not (folds[rows] == k).any()]
        if absent:
            raise SplitError(f"{protocol}: fold {k}: device(s) {', '.join(absent)} have no test recording")

    if protocol == "paper-gravity":
        untested = np.flatnonzero(folds == -1)
        if len(untested):
            raise SplitError(f"paper-gravity: every recording must be tested once, found training-only "
                             f"recordings {_describe(keys, untested)}")
        for device, rows in per_device:
            sizes = np.bincount(folds[rows], minlength=params.n_folds)
            if sizes.max() - sizes.min() > 1:
                raise SplitError(f"paper-gravity: device {device}: test fold sizes {sizes.tolist()} "
                                 "differ by more than one")
        return

    if protocol == "paper-rotated":
        u = _unit_gravity(recordings, keys)
        for k in range(params.n_folds):
            for device, rows in per_device:
                n_test = int((folds[rows] == k).sum())
                if n_test > params.test_per_fold:
                    raise SplitError(f"paper-rotated: fold {k}: device {device} has {n_test} test "
                                     f"recordings, more than test_per_fold = {params.test_per_fold}")
        group_of = np.empty(len(keys), dtype=np.int64)
        offset = 0
        for _, rows in per_device:
            # tilt groups never span devices: number them on after the previous device's
            labels = tilt_groups(u[rows], params.tilt_tolerance_deg)
            group_of[rows] = labels + offset
            offset += int(labels.max()) + 1 if len(labels) else 0
        _check_groups(keys, folds, group_of, params.n_folds, protocol, "shares a tilt group with")
        return

    instances = pd.DataFrame({"device": keys["device"], "power_cycle": _power_cycles(recordings, keys)})
    group_of = instances.groupby(["device", "power_cycle"], sort=True).ngroup().to_numpy(dtype=np.int64)
    _check_groups(keys, folds, group_of, params.n_folds, protocol,
                  "shares a bias instance (device, power_cycle) with")


def _check_groups(keys: pd.DataFrame, folds: np.ndarray, group_of: np.ndarray, n_folds: int,
                  protocol: str, relation: str) -> None:
    """Raise when some group has a test member of fold k and a training member of fold k."""
    for k in range(n_folds):
        test = folds == k
        test_groups = np.unique(group_of[test])
        leaky = np.isin(group_of, test_groups) & ~test
        if leaky.any():
            bad_groups = np.unique(group_of[leaky])
            offending_test = np.flatnonzero(test & np.isin(group_of, bad_groups))
            raise SplitError(f"{protocol}: fold {k}: test recording(s) {_describe(keys, offending_test)} "
                             f"{relation} training recording(s) {_describe(keys, np.flatnonzero(leaky))}")


def fold_summary(recordings: pd.DataFrame, folds: np.ndarray) -> pd.DataFrame:
    """Test and training counts per fold and device.

    Parameters
    ----------
    recordings
        Needs the ``device`` column.
    folds
        (n,) assignment aligned with ``recordings`` by position.

    Returns
    -------
    DataFrame
        Columns ``fold`` (int64), ``device`` (str), ``n_test``, ``n_train`` (int64), one row per
        fold ``0 … max(folds)`` and device, sorted by fold then device.
    """
    _check_columns(recordings, ("device",))
    folds = np.asarray(folds)
    if folds.shape != (len(recordings),):
        raise SplitError(f"folds: expected shape ({len(recordings)},), found {folds.shape}")
    devices = recordings["device"].astype(str).to_numpy(dtype=object)
    rows = []
    for k in range(int(folds.max()) + 1 if len(folds) else 0):
        for device in sorted(set(devices.tolist())):
            mine = devices == device
            n_test = int((mine & (folds == k)).sum())
            rows.append({"fold": k, "device": device, "n_test": n_test, "n_train": int(mine.sum()) - n_test})
    out = pd.DataFrame(rows, columns=["fold", "device", "n_test", "n_train"])
    return out.astype({"fold": np.int64, "n_test": np.int64, "n_train": np.int64})
