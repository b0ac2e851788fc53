"""Export a dataset: a verified copy with its package files rewritten (title, licence, authors),
for sharing. The copy always has the signal Parquet file(s) that Hugging Face ``datasets`` and
Croissant read: copied when the source has them, written from its HDF5 file(s) when it was built
before they existed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.atomic import atomic_directory, copy_file
from ofbe_data.core.errors import ConfigError, OutputExistsError
from ofbe_data.dataset.package import write_package_files
from ofbe_data.dataset.reader import read_dataset_info, verify_dataset
from ofbe_data.dataset.signals import write_signal_files
from ofbe_data.dataset.store import H5_NAME, PARQUET_NAME, DatasetError, shard_layout, signal_names

# ---------------------------------------------------------------------------------------------
# Export


def export_dataset(src: str | Path, dest: str | Path, *, title: str | None = None, licence: str | None = None,
                   authors: Sequence[str] | None = None, version: str | None = None,
                   force: bool = False) -> Path:
    """Copy a verified dataset to ``dest`` with its package files rewritten.

    The data files (``windows.h5``, or every shard of a sharded dataset, ``windows.parquet``
    and the signal Parquet file(s)) are copied byte for byte; ``datapackage.json``,
    ``croissant.json``, ``README.md``, ``CITATION.cff`` and ``SHA256SUMS`` are rewritten from the
    description stored in the dataset (so the export is self-contained) with the overrides given.
    A source without signal files (built before they existed) gets them written from its HDF5
    file(s). Without overrides the export is byte-identical to ``src`` (to a fresh export of it,
    for a source without signal files). The copy is verified before it is moved into place.

    Parameters
    ----------
    src
        A dataset folder.
    dest
        The new folder.
    title, licence, authors, version
        Overrides of the description (``None`` keeps the stored value).
    force
        Replace an existing ``dest`` (only once the new one is complete).

    Returns
    -------
    Path
        ``dest``.

    Raises
    ------
    OutputExistsError
        ``dest`` exists and ``force`` is not set.
    DatasetError
        ``src`` fails :func:`verify_dataset`, or an override is invalid.
    """
    src, dest = Path(src), Path(dest)
    listed = verify_dataset(src)["files"]
    if dest.exists() and not force:
        raise OutputExistsError(dest)
    info = read_dataset_info(src)
    overrides = {k: v for k, v in (("title", title), ("licence", licence), ("version", version),
                                   ("authors", tuple(authors) if authors is not None else None))
                 if v is not None}
    try:
        info = dataclasses.replace(info, **overrides)
    except ConfigError as exc:
        raise DatasetError(dest, exc.expected, exc.found, exc.key) from exc
    with atomic_directory(dest, replace=force) as tmp:
        shards = shard_layout(src)
        data_files = [H5_NAME] if shards is None else [name for name, _ in shards]
        signals = signal_names(shards)
        has_signals = all(name in listed for name in signals)  # checked against SHA256SUMS
        for name in (*data_files, PARQUET_NAME, *(signals if has_signals else ())):
            copy_file(src / name, tmp / name)
        if not has_signals:
            write_signal_files(tmp)
        write_package_files(tmp, info)
        verify_dataset(tmp)
    return dest

