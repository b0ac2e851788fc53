"""HDF5 chunks of ``X`` compressed where the windows are cut (in the workers), written as they are.

``X`` is stored one window per chunk, through the filters shuffle → gzip (level 4) →
Fletcher-32 (:data:`X_OPTIONS`). Compressing is most of a dataset writer's work, and one
process writes a file; so the workers that read the raw files also compress each window's
chunk, by HDF5 itself (a scratch file in memory with the same dataset options, whose chunks
are read back raw with ``read_direct_chunk``), and the writer puts the chunks into its file
with ``write_direct_chunk`` (:class:`ChunkSink`, in the order HDF5's chunk cache would place
them). The file is byte for byte the one HDF5 writes from the samples (tested), whichever
process compressed what.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ofbe_data.dataset.store import H5_LIBVER, DatasetError

Chunk = tuple[int, bytes]
"""One stored chunk: HDF5's filter mask (0: every filter applied) and its bytes."""

X_OPTIONS: dict[str, Any] = {"dtype": np.float32, "compression": "gzip", "compression_opts": 4,
                             "shuffle": True, "fletcher32": True, "track_times": False}
"""The options of every ``X`` dataset (besides its shape and one-window chunks)."""

_SCRATCH = itertools.count()


def x_dataset(group: h5py.Group, window_length: int, n: int = 0) -> h5py.Dataset:
    """Create ``X`` in ``group``: (n, T, 3) float32, growable, one window per chunk."""
    return group.create_dataset("X", shape=(n, window_length, 3), maxshape=(None, window_length, 3),
                                chunks=(1, window_length, 3), **X_OPTIONS)


def compress_windows(x: np.ndarray, source: str | Path) -> list[Chunk]:
    """The stored chunks of ``X`` for windows ``x``, compressed by HDF5's own filters.

    Parameters
    ----------
    x
        (n, T, 3) specific force, m/s² (stored as float32).
    source
        What the windows were cut from, named in errors.

    Returns
    -------
    list of (filter mask, bytes)
        One per window, in order.

    Raises
    ------
    DatasetError
        A non-finite sample (after conversion to float32), or not (n, T, 3).
    """
    x32 = np.asarray(x, dtype=np.float32)
    if x32.ndim != 3 or x32.shape[2] != 3:
        raise DatasetError(Path(source), "windows of shape (n, T, 3)", f"shape {x32.shape}", "X")
    finite = np.isfinite(x32)
    if not finite.all():
        raise DatasetError(Path(source), "finite samples (after conversion to float32)",
                           f"{int((~finite).sum())} non-finite", "X")
    if x32.shape[0] == 0:
        return []
    ds = _scratch(x32.shape[1])
    ds.resize(x32.shape[0], axis=0)
    ds[...] = x32
    return [ds.id.read_direct_chunk((i, 0, 0)) for i in range(x32.shape[0])]


_LOCAL = threading.local()
_SCRATCH_BYTES = 64 * 2**20
"""A thread's scratch file is made anew once its image passes this size (HDF5 reuses the space
of overwritten chunks, so it stays near one block's compressed size)."""


def _forget_scratch() -> None:
    """In a forked child: start with scratch files of its own."""
    _LOCAL.__dict__.pop("datasets", None)


os.register_at_fork(after_in_child=_forget_scratch)


def _scratch(window_length: int) -> h5py.Dataset:
    """This thread's scratch ``X`` for windows of ``window_length`` samples: an HDF5 file in
    memory (never on disk), kept between calls (making one costs about as much as compressing
    a window of 3000 samples)."""
    ds = getattr(_LOCAL, "datasets", {}).get(window_length)
    if ds is not None and ds.file.id.get_filesize() <= _SCRATCH_BYTES:
        return ds
    if ds is not None:
        ds.file.close()
    name = f"ofbe-chunks-{os.getpid()}-{next(_SCRATCH)}.h5"  # in memory only: never created on disk
    f = h5py.File(name, "w", libver=H5_LIBVER, driver="core", backing_store=False)
    ds = x_dataset(f, window_length, 1)
    _LOCAL.datasets = {**getattr(_LOCAL, "datasets", {}), window_length: ds}
    return ds


def decompress_chunk(chunk: Chunk, window_length: int) -> np.ndarray:
    """The samples of one stored chunk, (1, T, 3) float32 (HDF5's filters, in a scratch file)."""
    name = f"ofbe-chunks-{next(_SCRATCH)}.h5"
    with h5py.File(name, "w", libver=H5_LIBVER, driver="core", backing_store=False) as f:
        ds = x_dataset(f, window_length, 1)
        ds.id.write_direct_chunk((0, 0, 0), chunk[1], chunk[0])
        return np.asarray(ds[0:1])


class ChunkSink:
    """Store compressed chunks into an ``X`` dataset so that the file is the one HDF5 writes
    from the samples.

    Written from samples, a chunk goes into HDF5's chunk cache (``rdcc_nbytes``, 1 MiB by
    default: C = 1 MiB // (T·12 bytes) windows, in ``rdcc_nslots`` hash slots, 521 by default,
    window i in slot i mod 521) and gets its place in the file when the cache evicts it: when
    a newer window needs its slot, or the oldest when the cache is full, or at the file's
    flush; the chunk index (a B-tree) is made at the first write. ``write_direct_chunk``
    places a chunk at once. So the sink keeps the cache's book: it writes the first window
    from its samples (making the index and holding the window in HDF5's cache, as HDF5
    would), keeps the other windows' chunks in the same order and slots, and places each
    one when HDF5 would evict it (the first by flushing the dataset); :meth:`finish` places
    what the cache would still hold, after the file's other objects, just before the flush.
    Every allocation then happens in HDF5's own order: the bytes are those of the sample path
    (``tests/ofbe_data/dataset/test_sharding.py`` compares them for many window lengths and counts).
    """

    def __init__(self, ds: h5py.Dataset) -> None:
        self.ds = ds
        self.window_length = int(ds.shape[1])
        nslots, nbytes, _ = ds.id.get_access_plist().get_chunk_cache()
        self.nslots = max(int(nslots), 1)
        self.capacity = int(nbytes) // (self.window_length * 3 * 4)
        self._cache: dict[int, Chunk | None] = {}  # window → chunk, oldest first (None: in HDF5's)
        self._slots: dict[int, int] = {}  # hash slot → window

    def write(self, start: int, chunks: Sequence[Chunk]) -> None:
        """Grow ``X`` to ``start + len(chunks)`` windows and store the chunks at ``start``, …"""
        self.ds.resize(start + len(chunks), axis=0)
        for j, chunk in enumerate(chunks):
            index = start + j
            if self.capacity == 0:  # a chunk larger than the cache: HDF5 writes it at once
                self.ds.id.write_direct_chunk((index, 0, 0), chunk[1], chunk[0])
                continue
            slot = index % self.nslots
            if slot in self._slots:  # a newer window takes the slot: the older one is evicted
                self._evict(self._slots[slot])
            while len(self._cache) >= self.capacity:
                self._evict(next(iter(self._cache)))
            if index == 0:
                self.ds[0:1] = decompress_chunk(chunk, self.window_length)
                self._cache[0] = None
            else:
                self._cache[index] = chunk
            self._slots[slot] = index

    def finish(self) -> None:
        """Place what the cache would still hold (call after the file's other objects, before
        its flush)."""
        while self._cache:
            self._evict(next(iter(self._cache)))

    def _evict(self, index: int) -> None:
        chunk = self._cache.pop(index)
        del self._slots[index % self.nslots]
        if chunk is None:
            self.ds.id.flush()  # the first window, held in HDF5's own cache
        else:
            self.ds.id.write_direct_chunk((index, 0, 0), chunk[1], chunk[0])
