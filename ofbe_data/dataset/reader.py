"""Reading a dataset: headers, verification against the checksums, loading as numpy, pandas or tf.data."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.dataset.store import (
    _SUMS_LINE_RE,
    _TF_BLOCK,
    DATAPACKAGE_NAME,
    H5_NAME,
    PARQUET_NAME,
    RECORDING_KEY,
    SCHEMA_VERSION,
    SUMS_NAME,
    ChecksumError,
    DatasetError,
    _arrow_schema,
    _check_version,
    _read_h5_header,
    _read_json,
    _read_parquet_provenance,
    read_dataset_info,
    sha256_file,
)

# ---------------------------------------------------------------------------------------------
# Reading headers


# ---------------------------------------------------------------------------------------------
# Verification and loading


def _read_sums(path: Path) -> dict[str, str]:
    if not path.is_file():
        raise DatasetError(path, "a SHA256SUMS file", "no such file")
    sums: dict[str, str] = {}
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        m = _SUMS_LINE_RE.match(line)
        if m is None:
            raise DatasetError(path, "'<64 hex digits>  <file name>'", repr(line), f"line {i}")
        name = m.group(2)
        if "/" in name or "\\" in name or name in (".", ".."):
            raise DatasetError(path, "a plain file name of the dataset folder", repr(name), f"line {i}")
        sums[name] = m.group(1)
    for required in (H5_NAME, PARQUET_NAME, DATAPACKAGE_NAME):
        if required not in sums:
            raise DatasetError(path, f"a line for {required}", "none")
    return sums


def _compare_meta(h5_path: Path, pq_path: Path, table: pa.Table, protocols: Sequence[str]) -> None:
    """windows.h5 (y, meta/) and windows.parquet agree column by column and row by row."""
    schema = _arrow_schema(protocols)
    found = [f"{f.name}:{f.type}" for f in table.schema]
    if found != [f"{f.name}:{f.type}" for f in schema]:
        raise DatasetError(pq_path, f"the columns {[f'{f.name}:{f.type}' for f in schema]}", f"{found}")
    n = table.num_rows
    with h5py.File(h5_path, "r") as f:
        if "meta" not in f or "y" not in f:
            raise DatasetError(h5_path, "datasets X, y and group meta", f"{sorted(f)}")
        group = f["meta"]
        if sorted(group) != sorted(schema.names):
            raise DatasetError(h5_path, f"one dataset per column {sorted(schema.names)}", f"{sorted(group)}",
                               "meta")
        for fld in schema:
            ds = group[fld.name]
            if ds.shape != (n,):
                raise DatasetError(h5_path, f"shape ({n},) like {PARQUET_NAME}", f"{ds.shape}",
                                   f"meta/{fld.name}")
            col = table.column(fld.name)
            is_string = h5py.check_string_dtype(ds.dtype) is not None
            want = {pa.string(): "UTF-8 strings", pa.int64(): "int64", pa.float64(): "float64"}[fld.type]
            if (is_string != (fld.type == pa.string())
                    or (not is_string and ds.dtype != np.dtype(want))):
                raise DatasetError(h5_path, want, f"{ds.dtype}", f"meta/{fld.name}")
            if fld.type == pa.string():
                same = ds.asstr()[...].tolist() == col.to_pylist()
            else:
                same = np.array_equal(ds[...], col.to_numpy(), equal_nan=fld.type == pa.float64())
            if not same:
                raise DatasetError(h5_path, f"meta/{fld.name} equal to the column of {PARQUET_NAME}",
                                   "different values", f"meta/{fld.name}")
        y = f["y"]
        if y.shape != (n, 3) or y.dtype != np.float64:
            raise DatasetError(h5_path, f"float64 of shape ({n}, 3)", f"{y.dtype} {y.shape}", "y")
        bias = np.column_stack([table.column(f"bias_{a}").to_numpy() for a in "xyz"])
        if not np.array_equal(y[...], bias):
            raise DatasetError(h5_path, f"y equal to bias_x/y/z of {PARQUET_NAME}", "different values", "y")
    if not np.array_equal(table.column("window_id").to_numpy(), np.arange(n)):
        raise DatasetError(pq_path, "window_id = 0..N-1 in order", "other values", "window_id")


def verify_dataset(path: str | Path) -> dict[str, Any]:
    """Check a dataset folder: checksums, schema version, and that its files agree.

    Checks, in order: every file of ``SHA256SUMS`` exists and has its hash; the hashes and
    sizes of ``datapackage.json``'s resources; the schema version in ``windows.h5``,
    ``windows.parquet`` and ``datapackage.json``; the dataset description against the HDF5
    attributes; shapes and dtypes of ``X`` and ``y``; the Parquet schema; and ``meta/`` and ``y``
    against the Parquet columns, row by row. ``X`` itself is covered by the checksum (and by
    its chunks' Fletcher-32 sums when read).

    Returns
    -------
    dict
        ``path``, ``schema_version``, ``name``, ``campaign``, ``n_windows``, ``n_recordings``,
        ``n_devices``, ``window_length``, ``stride``, ``protocols`` and ``files`` (name → sha256).

    Raises
    ------
    ChecksumError
        A file's hash differs from the recorded one (naming the file and both hashes).
    DatasetError
        Anything else (naming the file, what was expected and what was found).
    """
    folder = Path(path)
    if not folder.is_dir():
        raise DatasetError(folder, "a dataset folder", "no such folder")
    sums_path = folder / SUMS_NAME
    sums = _read_sums(sums_path)
    actual: dict[str, str] = {}
    for name, expected in sums.items():
        file = folder / name
        if not file.is_file():
            raise DatasetError(file, f"a file listed in {SUMS_NAME}", "no such file")
        actual[name] = sha256_file(file)
        if actual[name] != expected:
            raise ChecksumError(file, f"sha256 {expected} (from {SUMS_NAME})", f"sha256 {actual[name]}")
    dp_path, h5_path, pq_path = folder / DATAPACKAGE_NAME, folder / H5_NAME, folder / PARQUET_NAME
    doc = _read_json(dp_path)
    resources = {r.get("path"): r for r in doc.get("resources", []) if isinstance(r, dict)}
    for name in (H5_NAME, PARQUET_NAME):
        res = resources.get(name)
        if res is None:
            raise DatasetError(dp_path, f"a resource with path {name!r}", "none", "resources")
        if res.get("hash") != f"sha256:{actual[name]}":
            raise ChecksumError(folder / name, f"{res.get('hash')} (from {DATAPACKAGE_NAME})",
                                f"sha256:{actual[name]}")
        size = (folder / name).stat().st_size
        if res.get("bytes") != size:
            raise DatasetError(dp_path, f"bytes = {size} (the size of {name})", repr(res.get("bytes")),
                               f"resources[{name}].bytes")
    attrs = _read_h5_header(h5_path)
    _check_version(h5_path, attrs.get("schema_version"))
    prov = _read_parquet_provenance(pq_path)
    _check_version(pq_path, prov.get("schema_version"))
    ofbe = doc.get("ofbe") if isinstance(doc.get("ofbe"), dict) else {}
    _check_version(dp_path, ofbe.get("schema_version"), "ofbe.schema_version")
    info = read_dataset_info(folder)
    for key in ("name", "campaign", "window_length", "stride", "protocols"):
        if prov.get(key) != attrs.get(key):
            raise DatasetError(pq_path, f"{attrs.get(key)!r} (as in {H5_NAME})", repr(prov.get(key)), key)
    t = info.window_length
    with h5py.File(h5_path, "r") as f:
        x = f.get("X")
        if not isinstance(x, h5py.Dataset) or x.dtype != np.float32 or x.shape[1:] != (t, 3):
            found = f"{x.dtype} {x.shape}" if isinstance(x, h5py.Dataset) else "none"
            raise DatasetError(h5_path, f"float32 of shape (N, {t}, 3)", found, "X")
        n = int(x.shape[0])
    table = pq.read_table(pq_path)
    if table.num_rows != n:
        raise DatasetError(pq_path, f"{n} rows (one per window of {H5_NAME})", f"{table.num_rows}")
    _compare_meta(h5_path, pq_path, table, list(info.protocols))
    keys = table.select(list(RECORDING_KEY)).to_pandas().drop_duplicates()
    return {"path": str(folder), "schema_version": SCHEMA_VERSION, "name": info.name,
            "campaign": info.campaign, "n_windows": n, "n_recordings": int(len(keys)),
            "n_devices": int(keys["device"].nunique()), "window_length": t, "stride": info.stride,
            "protocols": list(info.protocols), "files": dict(sorted(actual.items()))}


@dataclass(frozen=True, eq=False)
class LoadedDataset:
    """A dataset in memory.

    Attributes
    ----------
    X
        float32 (N, T, 3), m/s², sensor frame.
    y
        float64 (N, 3), m/s²: the apparent-bias labels.
    meta
        One row per window (the columns of ``windows.parquet``).
    info
        Root attributes of ``windows.h5`` (``protocols`` parsed) and ``dataset_info`` (the
        description from ``datapackage.json``).
    """

    X: np.ndarray
    y: np.ndarray
    meta: pd.DataFrame
    info: dict[str, Any]


_LOADERS = ("numpy", "pandas", "tf")


def _info_dict(folder: Path) -> dict[str, Any]:
    attrs = _read_h5_header(folder / H5_NAME)
    attrs.pop("n_windows", None)
    _check_version(folder / H5_NAME, attrs.get("schema_version"))
    pq_path = folder / PARQUET_NAME
    _check_version(pq_path, _read_parquet_provenance(pq_path).get("schema_version"))
    return {**attrs, "dataset_info": read_dataset_info(folder).to_dict()}


def _read_meta(folder: Path) -> pd.DataFrame:
    path = folder / PARQUET_NAME
    try:
        return pq.read_table(path).replace_schema_metadata(None).to_pandas()
    except (OSError, pa.ArrowException) as exc:
        raise DatasetError(path, "a readable Parquet file", f"an unreadable one ({exc})") from exc


def load_dataset(path: str | Path, as_: str = "numpy", verify: bool = True) -> Any:
    """Load a dataset folder.

    Parameters
    ----------
    path
        The dataset folder (``processed/datasets/<name>``).
    as_
        ``"numpy"``: a :class:`LoadedDataset` (X float32 (N, T, 3), y float64 (N, 3), meta, info).
        ``"pandas"``: the metadata frame alone (no X); its ``bias_x/y/z`` columns are ``y``
        (verified equal to ``windows.h5:/y``), and ``frame.attrs["ofbe"]`` holds ``info``.
        ``"tf"``: a ``tf.data.Dataset`` of ``(X_i, y_i)`` pairs, float32 (T, 3) and float64 (3,),
        in file order. X is *streamed*: a generator (with ``output_signature``) reads 256
        windows at a time from ``windows.h5`` on each pass, so the dataset need not fit in
        memory; ``y`` is held in memory. Cardinality is set to N. TensorFlow is imported here.
    verify
        Run :func:`verify_dataset` first (checksums, schema version, agreement of the files).
        Without it the schema version is still checked.

    Raises
    ------
    DatasetError
        On an unknown ``as_`` or a bad dataset (:class:`ChecksumError` for a hash mismatch).
    """
    folder = Path(path)
    if as_ not in _LOADERS:
        raise DatasetError(folder, f"as_ one of {list(_LOADERS)}", repr(as_), "as_")
    if verify:
        verify_dataset(folder)
    info = _info_dict(folder)
    if as_ == "pandas":
        meta = _read_meta(folder)
        meta.attrs["ofbe"] = info
        return meta
    h5_path = folder / H5_NAME
    if as_ == "numpy":
        try:
            with h5py.File(h5_path, "r") as f:
                x = np.asarray(f["X"][...], dtype=np.float32)
                y = np.asarray(f["y"][...], dtype=np.float64)
        except OSError as exc:  # e.g. a chunk failing its Fletcher-32 checksum
            raise DatasetError(h5_path, "readable X and y (chunks passing their Fletcher-32 checksums)",
                               f"a read error ({exc})") from exc
        return LoadedDataset(X=x, y=y, meta=_read_meta(folder), info=info)
    return _tf_dataset(h5_path, int(info["window_length"]))


def _window_generator(h5_path: Path, y: np.ndarray) -> Callable[[], Iterator[tuple[np.ndarray, np.ndarray]]]:
    def gen() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        with h5py.File(h5_path, "r") as f:
            x = f["X"]
            for start in range(0, x.shape[0], _TF_BLOCK):
                block = x[start:start + _TF_BLOCK]
                for i in range(block.shape[0]):
                    yield block[i], y[start + i]

    return gen


def _tf_dataset(h5_path: Path, window_length: int) -> Any:
    from ofbe_data.core.cli import import_tensorflow

    tf = import_tensorflow()

    with h5py.File(h5_path, "r") as f:
        y = np.asarray(f["y"][...], dtype=np.float64)
    signature = (tf.TensorSpec(shape=(window_length, 3), dtype=tf.float32),
                 tf.TensorSpec(shape=(3,), dtype=tf.float64))
    ds = tf.data.Dataset.from_generator(_window_generator(h5_path, y), output_signature=signature)
    return ds.apply(tf.data.experimental.assert_cardinality(len(y)))
