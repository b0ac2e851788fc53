"""Windows: the labelled stationary segments cut into fixed-length model inputs.

A label row (:mod:`ofbe_data.labelling.store`) names its raw file, the file's SHA-256 and the
first and last time stamp of the stationary segment it rests on. This module goes back to
that raw file (never to another stage's output), checks that it is the file that was
labelled, takes the same samples, and cuts them into windows of ``T`` samples with stride
``stride`` (methods.md §Protocols: T = 3000, 20 s at 150 Hz, non-overlapping). The first
window of a recording is its test signal.

Sessions are read in worker processes, at most a few ahead of the consumer, so a caller
that streams windows to disk never holds more than a few sessions in memory.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.lib.stride_tricks import sliding_window_view

from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import iter_ordered
from ofbe_data.dataset.chunks import Chunk, compress_windows
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import SessionManifest, load_manifest
from ofbe_data.labelling.labels import sha256_file


class SegmentError(OfbeError):
    """A label row's raw file is missing, changed since labelling, or no longer gives the
    labelled segment. The message names the file, what was expected and what was found."""

    def __init__(self, path: str | Path, expected: str, found: str) -> None:
        self.path = Path(path)
        self.expected = expected
        self.found = found
        super().__init__(f"{path}: expected {expected}, found {found}")


@dataclass(frozen=True)
class WindowParams:
    """Window length and stride, samples (``dataset.window_length`` / ``dataset.stride``)."""

    window_length: int = 3000
    stride: int = 3000


def n_windows(n_samples: int, window_length: int, stride: int) -> int:
    """Number of windows of ``window_length`` samples, ``stride`` apart, in ``n_samples``."""
    if n_samples < window_length:
        return 0
    return (n_samples - window_length) // stride + 1


def cut_windows(x: np.ndarray, window_length: int, stride: int) -> np.ndarray:
    """Cut a segment into windows.

    Parameters
    ----------
    x
        (n, 3) samples, m/s².
    window_length, stride
        Samples.

    Returns
    -------
    ndarray, shape (k, window_length, 3)
        A copy, k = :func:`n_windows`; window j starts at sample ``j·stride``.
    """
    k = n_windows(x.shape[0], window_length, stride)
    if k == 0:
        return np.empty((0, window_length, x.shape[1]), dtype=x.dtype)
    view = sliding_window_view(x, window_length, axis=0)[::stride][:k]  # (k, 3, T)
    return np.ascontiguousarray(view.transpose(0, 2, 1))


def segment_from_recording(t: np.ndarray, acc: np.ndarray, row: Mapping[str, Any], path: Path,
                           ) -> np.ndarray:
    """The labelled stationary samples of a recording, checked against the label row.

    Parameters
    ----------
    t
        (n,) sample times of the recording, s (its own clock, as the reader returns them).
    acc
        (n, 3) specific force, m/s².
    row
        A label row: ``segment_start_s``, ``segment_end_s`` and ``n_samples``.
    path
        The raw file, for messages.

    Returns
    -------
    ndarray, shape (n_samples, 3)

    Raises
    ------
    SegmentError
        The time stamps do not give ``n_samples`` samples.
    """
    a = int(np.searchsorted(t, row["segment_start_s"], side="left"))
    b = int(np.searchsorted(t, row["segment_end_s"], side="right"))
    if b - a != int(row["n_samples"]) or a >= t.shape[0] or t[a] != row["segment_start_s"]:
        raise SegmentError(path, f"{int(row['n_samples'])} samples from t = {row['segment_start_s']!r} s "
                                 f"to {row['segment_end_s']!r} s (the labelled segment)",
                           f"{b - a} samples there")
    return acc[a:b]


def load_segments(session_dir: str | Path, rows: Sequence[Mapping[str, Any]],
                  manifest: SessionManifest | None = None) -> list[np.ndarray]:
    """The stationary samples of label rows of one session, read again from the raw files.

    Parameters
    ----------
    session_dir
        The session folder the rows were labelled from (its ``session.yaml``).
    rows
        Label rows of that session (``device``, ``raw_file``, ``raw_sha256``,
        ``segment_start_s``, ``segment_end_s``, ``n_samples``).
    manifest
        The session's manifest when already loaded.

    Returns
    -------
    list of ndarray, each (n_samples, 3) m/s²
        In the order of ``rows``.

    Raises
    ------
    SegmentError
        A file is missing, its SHA-256 differs from the labelled file's, or the labelled
        segment is not where the label says.
    """
    session_dir = Path(session_dir)
    m = manifest if manifest is not None else load_manifest(session_dir)
    out = []
    for row in rows:
        path = m.folder / row["raw_file"]
        if not path.is_file():
            raise SegmentError(path, "the raw file the label was made from", "no such file")
        digest = sha256_file(path)
        if digest != row["raw_sha256"]:
            raise SegmentError(path, f"SHA-256 {row['raw_sha256']} (the file that was labelled)",
                               f"{digest}: the file changed after labelling; label it again")
        rec = read_device_file(path, m.devices[row["device"]])
        out.append(segment_from_recording(rec.t, rec.acc, row, path))
    return out


def session_windows(session_dir: str | Path, rows: Sequence[Mapping[str, Any]],
                    params: WindowParams) -> list[np.ndarray]:
    """Windows of each label row of one session: a list of (k_i, T, 3) float32 arrays, m/s²."""
    segments = load_segments(session_dir, rows)
    return [cut_windows(seg, params.window_length, params.stride).astype(np.float32) for seg in segments]


def session_chunks(session_dir: str | Path, rows: Sequence[Mapping[str, Any]],
                   params: WindowParams) -> list[list[Chunk]]:
    """:func:`session_windows`, compressed where they are cut: per label row, one stored HDF5
    chunk per window (:func:`ofbe_data.dataset.chunks.compress_windows`)."""
    source = Path(session_dir)
    return [compress_windows(x, source / str(row["raw_file"]))
            for x, row in zip(session_windows(session_dir, rows, params), rows, strict=True)]


def _session_job(args: tuple[Path, list[dict[str, Any]], WindowParams]) -> list[np.ndarray]:
    return session_windows(*args)


def _session_chunks_job(args: tuple[Path, list[dict[str, Any]], WindowParams]) -> list[list[Chunk]]:
    return session_chunks(*args)


def iter_windows(labels: pd.DataFrame, raw_dir: str | Path, params: WindowParams, jobs: int = 1,
                 ahead: int = 2, compressed: bool = False, scheduler: str = "processes"
                 ) -> Iterator[tuple[int, Any]]:
    """Windows of every label row, session by session, streamed.

    Parameters
    ----------
    labels
        Label rows (:func:`ofbe_data.labelling.store.read_labels`), each with its ``session``;
        the session folder is ``raw_dir / session``.
    raw_dir
        The raw campaign folder.
    params
        Window length and stride.
    jobs
        Workers (1 with the local pool: read in this process).
    ahead
        Sessions in flight per worker beyond the one being consumed: bounds memory.
    compressed
        Yield each row's windows as stored HDF5 chunks (:func:`session_chunks`: the workers
        compress them) instead of samples.
    scheduler
        Where the workers run (:mod:`ofbe_data.core.scheduler`): ofbe's own process pool, whose
        Ctrl-C is one line, or Dask.

    Yields
    ------
    (index, windows)
        ``index`` is the row's index label in ``labels``; ``windows`` is (k, T, 3) float32,
        k possibly 0 (or k chunks with ``compressed``). Rows come in the order of ``labels``'
        sessions as first seen.
    """
    raw_dir = Path(raw_dir)
    groups: list[tuple[Path, list[Any], list[dict[str, Any]]]] = []
    for session, frame in labels.groupby("session", sort=False):
        groups.append((raw_dir / str(session), list(frame.index), frame.to_dict("records")))
    read, job = (session_chunks, _session_chunks_job) if compressed else (session_windows, _session_job)
    if jobs <= 1 and scheduler == "processes":
        for folder, index, rows in groups:
            yield from zip(index, read(folder, rows, params), strict=True)
        return
    results = iter_ordered(job, [(folder, rows, params) for folder, _, rows in groups], jobs=jobs,
                           ahead=ahead, scheduler=scheduler, name=lambda task: f"session {task[0]}")
    for (_, index, _), result in zip(groups, results, strict=True):
        yield from zip(index, result, strict=True)
