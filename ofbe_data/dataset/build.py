"""Building a dataset: labels + raw files → windows, fold assignments, a shareable folder.

One dataset per campaign (products.md §Dataset). The label rows of the campaign are read
(:func:`ofbe_data.labelling.store.read_labels`); recordings whose stationary segment is shorter
than one window are left out (and listed); the protocols that apply to the campaign's kind
assign 5-fold test folds at the recording level (:mod:`ofbe_data.dataset.splits`); then the raw
files are read again session by session (:mod:`ofbe_data.dataset.windows`), cut into windows and
streamed into ``windows.h5`` (or, above ``shard_windows`` windows, into shard files
``windows-00000.h5``, …) while the per-window metadata accumulates for ``windows.parquet``
(:mod:`ofbe_data.dataset.store`). The folder is built under a temporary name and renamed when
complete.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from ofbe_data.core.atomic import atomic_directory
from ofbe_data.core.errors import ConfigError, OfbeError, OutputExistsError
from ofbe_data.dataset.fidelity import label_fidelity
from ofbe_data.dataset.splits import PROTOCOLS, SplitParams, assign_folds
from ofbe_data.dataset.store import DEFAULT_SHARD_WINDOWS, DatasetInfo, fold_column
from ofbe_data.dataset.windows import SegmentError, WindowParams, iter_windows, n_windows
from ofbe_data.dataset.writer import WindowWriter
from ofbe_data.io.typedconfig import from_plain
from ofbe_data.labelling.store import read_labels

PROTOCOL_TEXT = {
    "paper-gravity": "The paper's protocol for the gravity-aligned set: per device, recordings dealt at "
                     "random into 5 folds (80/20), every device in every test fold. Recordings that share "
                     "a power cycle may fall on both sides of a fold.",
    "paper-rotated": "The paper's protocol for the rotated set: per device, 9 test recordings per fold, "
                     "whole tilt groups at a time, so no test tilt is seen in that fold's training set; the "
                     "other recordings only train. Recordings of one power cycle may fall on both sides.",
    "grouped": "Leakage-free: per device, folds split by power cycle, so no bias instance is both "
               "trained on and tested.",
}
"""What each protocol is, for dataset cards."""

DEFAULT_PROTOCOLS = {
    "gravity-aligned": ("paper-gravity", "grouped"),
    "rotated": ("paper-rotated", "grouped"),
    "multi-position": ("grouped",),
}

#: Label columns carried to every window of the recording.
_CARRIED = ("campaign", "session", "recording", "device", "power_cycle", "bias_x", "bias_y", "bias_z",
            "offset_x", "offset_y", "offset_z", "gravity_x", "gravity_y", "gravity_z", "roll_deg",
            "pitch_deg", "g_local", "fs_hz", "label_method", "raw_sha256")


@dataclass(frozen=True)
class DatasetParams:
    """Parameters of dataset building (``dataset:`` in params.yaml).

    Attributes
    ----------
    window_length, stride
        Samples per window and between window starts (methods.md: 3000 and 3000).
    n_folds, seed
        Cross-validation folds and the seed of every protocol's shuffle.
    test_per_fold
        ``paper-rotated``: test recordings per fold and device.
    tilt_tolerance_deg
        ``paper-rotated``: two recordings whose gravity directions are closer than this
        share a tilt.
    protocols
        Session kind → protocols written for a campaign of that kind.
    licence
        SPDX id of the data licence written on the card.
    shard_windows
        Windows per HDF5 file: a dataset of more windows is written as shards
        ``windows-00000.h5``, … of this many windows, indexed by ``windows.parquet``; one of at
        most this many keeps the single ``windows.h5`` (the default,
        :data:`~ofbe_data.dataset.store.DEFAULT_SHARD_WINDOWS`, leaves the paper's datasets whole).
    """

    window_length: int = 3000
    stride: int = 3000
    n_folds: int = 5
    seed: int = 0
    test_per_fold: int = 9
    tilt_tolerance_deg: float = 0.5
    protocols: dict[str, tuple[str, ...]] = field(default_factory=lambda: dict(DEFAULT_PROTOCOLS))
    licence: str = "CC-BY-4.0"
    shard_windows: int = DEFAULT_SHARD_WINDOWS

    @property
    def windows(self) -> WindowParams:
        return WindowParams(self.window_length, self.stride)

    @property
    def split(self) -> SplitParams:
        return SplitParams(n_folds=self.n_folds, seed=self.seed, test_per_fold=self.test_per_fold,
                           tilt_tolerance_deg=self.tilt_tolerance_deg)


def dataset_params_from(data: dict[str, Any] | None, source: str | Path = "<parameters>") -> DatasetParams:
    """:class:`DatasetParams` from a plain mapping, checked.

    Raises
    ------
    ConfigError
        Unknown key, wrong type, a length, stride or shard size < 1, or an unknown protocol.
    """
    plain = dict(data or {})
    if "protocols" in plain and isinstance(plain["protocols"], dict):
        plain["protocols"] = {**DEFAULT_PROTOCOLS, **plain["protocols"]}
    params: DatasetParams = from_plain(plain, DatasetParams, source, "dataset")
    if params.window_length < 1 or params.stride < 1:
        raise ConfigError(source, "dataset.window_length/stride", "integers ≥ 1",
                          f"{params.window_length}, {params.stride}")
    if params.shard_windows < 1:
        raise ConfigError(source, "dataset.shard_windows", "an integer ≥ 1 (windows per shard file)",
                          str(params.shard_windows))
    for kind, names in params.protocols.items():
        for name in names:
            if name not in PROTOCOLS:
                raise ConfigError(source, f"dataset.protocols.{kind}",
                                  "protocols among " + ", ".join(PROTOCOLS), repr(name))
    return params


@dataclass(frozen=True)
class BuildResult:
    """What a build wrote.

    Attributes
    ----------
    path
        The dataset folder.
    n_windows
        Windows written.
    n_recordings
        Recordings with at least one window.
    excluded
        Recordings left out (segment shorter than one window), as label identities.
    protocols
        Protocols written.
    n_shards
        HDF5 files written: 1 for ``windows.h5``, else the shards.
    """

    path: Path
    n_windows: int
    n_recordings: int
    excluded: tuple[str, ...]
    protocols: tuple[str, ...]
    n_shards: int = 1


def _describe(raw_dir: Path, labels: pd.DataFrame, simulated: bool) -> str:
    devices = ", ".join(sorted(labels["device"].unique()))
    sessions = labels["session"].nunique()
    if simulated:
        return (f"Simulated with the ofbe campaign simulator (`ofbe-simulate`) into `{raw_dir}`: "
                f"{sessions} sessions, devices {devices}. The sensor model follows the ADXL345 datasheet and "
                "the paper's published statistics (see the toolkit's docs/sensor-model.md); each session is "
                "logged in the raw formats of real rigs and read back through the same validating readers. "
                "The simulator's truth files are not part of this dataset.")
    return (f"Recorded sessions from `{raw_dir}`: {sessions} sessions, devices {devices}. See each "
            "session's `session.yaml` for the site, the devices and their mounting.")


def _labelling_text(labels: pd.DataFrame) -> str:
    methods = ", ".join(f"{m} ({n})" for m, n in labels["label_method"].value_counts().sort_index().items())
    return ("Labels are the apparent bias b_app = mean(f) − g_local·u over each recording's stationary "
            "segment (ofbe-label; the ofbe toolkit's docs/labelling.md): u is the nearest sensor axis for "
            "a levelled device, the reference's gravity direction through Rodrigues' rotation for rotated "
            "sessions, or the norm-constrained pose fit for multi-position sessions. Where a campaign fit "
            "determines it, the zero-g offset b is given as offset_x/y/z. Label methods: " + methods
            + ". The label rests on the whole segment, so every window of a recording carries the same "
            "label.")


def build_dataset(labels_dir: str | Path, raw_dir: str | Path, out_dir: str | Path,
                  params: DatasetParams | None = None, *, name: str | None = None,
                  truth_dir: str | Path | None = None, jobs: int = 1, force: bool = False,
                  progress: bool = True, scheduler: str = "processes") -> BuildResult:
    """Build one campaign's dataset folder.

    Parameters
    ----------
    labels_dir
        The campaign's label folder (``processed/labels/<campaign>``).
    raw_dir
        The raw campaign folder the labels were made from (``raw/<campaign>``).
    out_dir
        The dataset folder to write (``processed/datasets/<name>``).
    params
        Windowing, folds and protocols.
    name
        Dataset name (default: the campaign).
    truth_dir
        The simulator's truth folder: when given, the card states the label fidelity.
    jobs
        Worker processes reading raw files.
    force
        Replace an existing ``out_dir`` (only once the new one is complete).
    progress
        Show a progress bar.
    scheduler
        Where raw files are read: ``processes``, ``dask`` or ``tcp://host:port``
        (:mod:`ofbe_data.core.parallel`); the dataset is the same whatever it is.

    Returns
    -------
    BuildResult

    Raises
    ------
    OfbeError
        No labels, several campaigns or kinds in the folder, a protocol that cannot be
        applied (:class:`ofbe_data.dataset.splits.SplitError`), a raw file changed since labelling
        (:class:`ofbe_data.dataset.windows.SegmentError`), or an existing ``out_dir`` without ``force``.
    """
    params = params or DatasetParams()
    labels_dir, raw_dir, out_dir = Path(labels_dir), Path(raw_dir), Path(out_dir)
    if out_dir.exists() and not force:
        raise OutputExistsError(out_dir)
    labels = read_labels(labels_dir)
    if labels.empty:
        raise OfbeError(f"{labels_dir}: expected label files (<session>.parquet) of one campaign, found none")
    for col in ("campaign", "kind"):
        values = sorted(labels[col].unique())
        if len(values) != 1:
            raise OfbeError(f"{labels_dir}: expected the labels of one campaign and kind, found {col}s "
                            + ", ".join(values))
    campaign, kind = str(labels["campaign"].iloc[0]), str(labels["kind"].iloc[0])
    labels = labels.sort_values(["session", "recording", "device"], kind="stable").reset_index(drop=True)
    w = params.windows
    counts = np.array([n_windows(int(n), w.window_length, w.stride) for n in labels["n_samples"]])
    short = labels[counts == 0]
    excluded = tuple(f"{r.session}/{r.recording}/{r.device}" for r in short.itertuples())
    labels = labels[counts > 0].reset_index(drop=True)
    counts = counts[counts > 0]
    if labels.empty:
        raise OfbeError(f"{labels_dir}: expected recordings with at least {w.window_length} stationary "
                        f"samples (one window), found none of {len(short)}")
    protocols = params.protocols.get(kind, ("grouped",))
    folds = {p: assign_folds(labels, p, params.split) for p in protocols}
    simulated = truth_dir is not None and Path(truth_dir).is_dir()
    info = DatasetInfo(
        name=name or campaign, campaign=campaign, kind=kind,
        title=f"ofbe {kind} windows: campaign {campaign}",
        description=_describe(raw_dir, labels, simulated), labelling=_labelling_text(labels),
        window_length=w.window_length, stride=w.stride, fs_hz=float(np.round(labels["fs_hz"].median(), 3)),
        protocols={p: {"description": PROTOCOL_TEXT[p], "n_folds": params.n_folds, "seed": params.seed,
                       **({"test_per_fold": params.test_per_fold,
                           "tilt_tolerance_deg": params.tilt_tolerance_deg} if p == "paper-rotated" else {})}
                   for p in protocols},
        licence=params.licence,
        label_fidelity=label_fidelity(labels, truth_dir, maps=False, shares=False) if simulated else None,
        extra={"n_recordings": len(labels), "excluded_recordings": list(excluded),
               "excluded_reason": f"stationary segment shorter than one window ({w.window_length} samples)",
               "devices": sorted(labels["device"].unique().tolist())},
    )
    # every window's metadata at once (the windows per recording follow from the labels), checked
    # once; the workers cut and compress the windows, the writer stores their chunks as they are
    rows = np.repeat(np.arange(len(labels)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)])
    meta = labels[list(_CARRIED)].iloc[rows].reset_index(drop=True)
    window_index = np.arange(len(rows), dtype=np.int64) - np.repeat(starts[:-1], counts)
    meta.insert(5, "window_index", window_index)
    meta.insert(6, "start_sample", window_index * w.stride)
    for p in protocols:
        meta[fold_column(p)] = np.asarray(folds[p], dtype=np.int64)[rows]
    bar = tqdm(total=int(counts.sum()), desc=f"windows {campaign}", unit="window", file=sys.stderr,
               disable=not progress)
    total = 0
    with (atomic_directory(out_dir, replace=force) as tmp,
          WindowWriter(tmp, info, shard_windows=params.shard_windows) as writer):
        cols = writer.normalise_meta(meta)
        # each row's windows as stored HDF5 chunks, compressed in the workers (sessions in order)
        for i, chunks in iter_windows(labels, raw_dir, w, jobs=jobs, compressed=True, scheduler=scheduler):
            k = len(chunks)
            if k != counts[i]:
                r = labels.iloc[i]
                raise SegmentError(Path(raw_dir) / str(r["session"]) / str(r["raw_file"]),
                                   f"{counts[i]} windows (from the label's {int(r['n_samples'])} samples)",
                                   f"{k}")
            writer.append_chunks(chunks, {c: v[starts[i]:starts[i + 1]] for c, v in cols.items()})
            total += k
            bar.update(k)
    bar.close()
    return BuildResult(out_dir, total, len(labels), excluded, tuple(protocols), writer.n_shards)
