"""Which windows train and which test, per benchmark dataset, protocol and fold.

The paper evaluates the gravity-aligned set pooled over its devices, and each rotated
SparkFun separately; this module turns a windowed dataset (docs/datasets.md) into those
benchmark datasets and, for a protocol, into folds:

- training windows of fold k: every window of a recording whose ``fold_<protocol>`` is not k
  (recordings with −1 only ever train);
- test signals of fold k: window 0 (``window_index == 0``) of every recording whose fold is k
  (methods.md: the first T samples of the stationary segment).

Both ``ofbe-train`` and ``ofbe-benchmark`` use these functions, so a model is always tested
on exactly the signals its training excluded; the deployed models are fitted per benchmark
dataset. They belong to the dataset wing: which windows train and which test is a property of
the dataset and its protocols, not of any estimator.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError
from ofbe_data.dataset.store import fold_column


class FoldError(OfbeError):
    """A dataset has no column for the protocol asked for, or a fold without a test signal."""


POOLED_KINDS = ("gravity-aligned",)
"""Kinds evaluated pooled over devices (the paper's gravity-aligned set); other kinds are
evaluated per device (the paper's rotated SparkFuns)."""


@dataclass(frozen=True)
class Split:
    """One fold of one benchmark dataset.

    Attributes
    ----------
    dataset
        Benchmark dataset name: the campaign (pooled) or ``<campaign>/<device>``.
    devices
        Devices in it.
    fold
        Test fold index.
    train, test
        Row positions (into the dataset's window table) of the training windows and of the
        test signals, ascending.
    """

    dataset: str
    devices: tuple[str, ...]
    fold: int
    train: np.ndarray
    test: np.ndarray


def benchmark_datasets(meta: pd.DataFrame, kind: str) -> list[tuple[str, tuple[str, ...], np.ndarray]]:
    """The benchmark datasets of one windowed dataset: (name, devices, row positions).

    Parameters
    ----------
    meta
        The window table (``windows.parquet``), with ``campaign`` and ``device``.
    kind
        The campaign's session kind.
    """
    campaign = str(meta["campaign"].iloc[0])
    devices = tuple(sorted(meta["device"].unique()))
    if kind in POOLED_KINDS:
        return [(campaign, devices, np.arange(len(meta)))]
    dev = meta["device"].to_numpy()
    return [(f"{campaign}/{d}", (d,), np.flatnonzero(dev == d)) for d in devices]


def protocol_splits(meta: pd.DataFrame, kind: str, protocol: str) -> Iterator[Split]:
    """Every fold of every benchmark dataset under one protocol.

    Raises
    ------
    FoldError
        The dataset has no column for the protocol, or a fold has no test signal.
    """
    col = fold_column(protocol)
    if col not in meta.columns:
        have = sorted(c.removeprefix("fold_") for c in meta.columns if c.startswith("fold_"))
        raise FoldError(f"protocol: expected one of this dataset's protocols ({', '.join(have)}), "
                             f"found {protocol!r}")
    folds = meta[col].to_numpy()
    first = meta["window_index"].to_numpy() == 0
    for name, devices, rows in benchmark_datasets(meta, kind):
        f = folds[rows]
        for k in sorted(int(v) for v in np.unique(f) if v >= 0):
            train = rows[f != k]
            test = rows[(f == k) & first[rows]]
            if test.size == 0:
                raise FoldError(f"{name}, {protocol} fold {k}: expected test signals, found none")
            yield Split(name, devices, k, train, test)
