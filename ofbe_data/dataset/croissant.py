"""``croissant.json``: the dataset folder described in MLCommons Croissant 1.1 (JSON-LD).

Croissant 1.1 rather than 1.0 because 1.1 states an array's shape (``isArray`` and
``arrayShape``); 1.0 only has ``repeated``, a flat list. The document is written by the toolkit
alone (``mlcroissant`` is not needed to write it) and is what ``mlcroissant`` 1.1 reads without
errors (the test suite checks it):

``distribution``
    One ``cr:FileObject`` per data file, with ``contentSize``, ``encodingFormat`` and
    ``sha256``: the HDF5 file(s) (``application/x-hdf5``; no record set reads them, Croissant
    readers have no HDF5 reader), ``windows.parquet`` and the signal file(s)
    (``application/x-parquet``). A sharded dataset adds the ``cr:FileSet`` ``signal-files``
    (``includes: signals-*.parquet``) that the record set ``signals`` reads.
``recordSet``
    ``windows``: one record per window from ``windows.parquet`` (labels, metadata, folds), key
    ``window_id``. ``signals``: the same columns (less the shard index) plus ``X``, the window, a
    float32 array of shape (T, 3) in m/s², read from the signal file(s).

Nothing in it depends on the time or the machine: the same folder gives the same bytes. It has
no ``datePublished`` (a build has no publication date; ``mlcroissant`` reports its absence as a
warning, not an error).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ofbe_data.dataset.store import (
    H5_NAME,
    PAPER_AUTHORS,
    PAPER_TITLE,
    PARQUET_NAME,
    SHARD_COLUMNS,
    SIGNAL_COLUMN,
    UNITS,
    ColumnSpec,
    DatasetInfo,
    all_columns,
)

CROISSANT_VERSION = "http://mlcommons.org/croissant/1.1"
PARQUET_MEDIATYPE = "application/x-parquet"
HDF5_MEDIATYPE = "application/x-hdf5"
#: ``@id`` of the FileSet of a sharded dataset's signal files.
SIGNAL_FILESET = "signal-files"

#: The JSON-LD context of Croissant 1.1, as ``mlcroissant`` writes it.
CONTEXT: dict[str, Any] = {
    "@language": "en",
    "@vocab": "https://schema.org/",
    "arrayShape": "cr:arrayShape",
    "citeAs": "cr:citeAs",
    "column": "cr:column",
    "conformsTo": "dct:conformsTo",
    "containedIn": "cr:containedIn",
    "cr": "http://mlcommons.org/croissant/",
    "data": {"@id": "cr:data", "@type": "@json"},
    "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "dct": "http://purl.org/dc/terms/",
    "description": {"@container": "@language"},
    "equivalentProperty": "cr:equivalentProperty",
    "examples": {"@id": "cr:examples", "@type": "@json"},
    "extract": "cr:extract",
    "field": "cr:field",
    "fileObject": "cr:fileObject",
    "fileProperty": "cr:fileProperty",
    "fileSet": "cr:fileSet",
    "format": "cr:format",
    "includes": "cr:includes",
    "isArray": "cr:isArray",
    "isLiveDataset": "cr:isLiveDataset",
    "jsonPath": "cr:jsonPath",
    "key": "cr:key",
    "md5": "cr:md5",
    "name": {"@container": "@language"},
    "parentField": "cr:parentField",
    "path": "cr:path",
    "rai": "http://mlcommons.org/croissant/RAI/",
    "recordSet": "cr:recordSet",
    "references": "cr:references",
    "regex": "cr:regex",
    "repeated": "cr:repeated",
    "replace": "cr:replace",
    "samplingRate": "cr:samplingRate",
    "sc": "https://schema.org/",
    "separator": "cr:separator",
    "source": "cr:source",
    "subField": "cr:subField",
    "transform": "cr:transform",
}

_DATA_TYPES = {"string": "sc:Text", "int": "cr:Int64", "float": "cr:Float64"}


def _file_object(name: str, size: int, digest: str, mediatype: str, description: str) -> dict[str, Any]:
    return {"@type": "cr:FileObject", "@id": name, "name": name, "description": description,
            "contentUrl": name, "contentSize": f"{size} B", "encodingFormat": mediatype, "sha256": digest}


def _field(record_set: str, col: ColumnSpec, source: dict[str, Any]) -> dict[str, Any]:
    text = col.description + (f" ({col.unit})" if col.unit else "") + (
        "; null when unknown" if col.nullable else "")
    return {"@type": "cr:Field", "@id": f"{record_set}/{col.name}", "name": col.name, "description": text,
            "dataType": _DATA_TYPES[col.kind], "source": {**source, "extract": {"column": col.name}}}


def _licence_url(licence: str, urls: Mapping[str, str]) -> str:
    return urls.get(licence, licence)


def croissant_document(info: DatasetInfo, files: Mapping[str, tuple[int, str]],
                       layout: Sequence[tuple[str, int]] | None, signals: Sequence[str] | None,
                       licence_urls: Mapping[str, str]) -> dict[str, Any]:
    """The Croissant 1.1 JSON-LD document of a dataset folder.

    Parameters
    ----------
    info
        The dataset description.
    files
        ``{file name: (bytes, sha256 hex)}`` of every data file: the HDF5 file(s),
        ``windows.parquet`` and the signal file(s).
    layout
        :func:`~ofbe_data.dataset.store.shard_layout` of the folder (``None``: one ``windows.h5``).
    signals
        The signal Parquet files in window order, or ``None`` when the folder has none (then there
        is no ``signals`` record set).
    licence_urls
        SPDX id → licence URL, for ``license`` (an unknown id is written as is).

    Returns
    -------
    dict
        The JSON-LD document, ready for :func:`json.dumps`.
    """
    t = info.window_length
    sharded = layout is not None
    protocols = list(info.protocols)
    h5_files = [(H5_NAME, None)] if layout is None else list(layout)
    distribution: list[dict[str, Any]] = []
    for i, (name, n) in enumerate(h5_files):
        size, digest = files[name]
        what = f"windows.h5: X float32 (N, {t}, 3) {UNITS}, y float64 (N, 3), meta/" if n is None else (
            f"HDF5 shard {i}: X float32 ({n}, {t}, 3) {UNITS}, y float64 ({n}, 3), meta/")
        distribution.append(_file_object(name, size, digest, HDF5_MEDIATYPE,
                                         what + " (the toolkit's own store; not read by a record set)"))
    size, digest = files[PARQUET_NAME]
    distribution.append(_file_object(PARQUET_NAME, size, digest, PARQUET_MEDIATYPE,
                                     "one row per window: labels, metadata, folds (no samples)"))
    for i, name in enumerate(signals or ()):
        size, digest = files[name]
        distribution.append(_file_object(
            name, size, digest, PARQUET_MEDIATYPE,
            f"the rows of {PARQUET_NAME}" + (f" in HDF5 shard {i}" if sharded else "")
            + f" with the window itself, column {SIGNAL_COLUMN}: float32 ({t}, 3) {UNITS}"))
    if signals and sharded:
        distribution.append({"@type": "cr:FileSet", "@id": SIGNAL_FILESET, "name": SIGNAL_FILESET,
                             "description": "the signal files of the shards, in window order",
                             "encodingFormat": PARQUET_MEDIATYPE, "includes": "signals-*.parquet"})
    windows_src = {"fileObject": {"@id": PARQUET_NAME}}
    record_sets: list[dict[str, Any]] = [{
        "@type": "cr:RecordSet", "@id": "windows", "name": "windows",
        "description": "one record per window: identity, label (bias_x/y/z), metadata and the test fold "
                       "of each protocol (fold_<protocol>, -1: training only)",
        "key": {"@id": "windows/window_id"},
        "field": [_field("windows", c, windows_src) for c in all_columns(protocols, sharded)]}]
    if signals:
        src = {"fileSet": {"@id": SIGNAL_FILESET}} if sharded else {"fileObject": {"@id": signals[0]}}
        columns = [c for c in all_columns(protocols, sharded) if c.name not in SHARD_COLUMNS]
        record_sets.append({
            "@type": "cr:RecordSet", "@id": "signals", "name": "signals",
            "description": f"one record per window with its samples: X, float32 array ({t}, 3), axes "
                           f"(sample, x/y/z), {UNITS}, sensor frame, plus the columns of windows",
            "key": {"@id": "signals/window_id"},
            "field": [*(_field("signals", c, src) for c in columns),
                      {"@type": "cr:Field", "@id": f"signals/{SIGNAL_COLUMN}", "name": SIGNAL_COLUMN,
                       "description": f"the window: specific force, {UNITS}, sensor frame, axes "
                                      f"(sample, x/y/z), {t} samples at {info.fs_hz:g} Hz",
                       "dataType": "cr:Float32", "isArray": True, "arrayShape": f"{t},3",
                       "source": {**src, "extract": {"column": SIGNAL_COLUMN}}}]})
    cite = (f"{', '.join(info.authors)}: {info.title}, version {info.version} (dataset). "
            f"{' & '.join(PAPER_AUTHORS)}: {PAPER_TITLE}.")
    return {
        "@context": CONTEXT,
        "@type": "sc:Dataset",
        "name": info.name,
        "description": info.description.strip() or info.title,
        "conformsTo": CROISSANT_VERSION,
        "alternateName": info.title,
        "citeAs": cite,
        "license": _licence_url(info.licence, licence_urls),
        "version": info.version,
        "keywords": ["accelerometer", "bias estimation", "IMU", "stationary", "time series"],
        "distribution": distribution,
        "recordSet": record_sets,
    }
