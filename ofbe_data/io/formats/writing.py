"""Writing vendor-style CSV files: data lines formatted by pyarrow, fixed-point decimals,
the preamble and an optional hook that garbles lines (the simulator's serial link).

Shared by the format modules' writers; re-exported by :mod:`~ofbe_data.io.formats.common`.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv


def csv_body(columns: Sequence[pa.Array], delimiter: str = ",") -> bytes:
    """Data lines (no header) of equal-length columns, formatted by pyarrow."""
    table = pa.table(list(columns), names=[f"c{i}" for i in range(len(columns))])
    buf = io.BytesIO()
    pacsv.write_csv(table, buf, pacsv.WriteOptions(include_header=False, quoting_style="none",
                                                   delimiter=delimiter))
    return buf.getvalue()


def fixed_point(values: np.ndarray, decimals: int) -> pa.Array:
    """A pyarrow decimal array that prints ``values`` with exactly ``decimals`` decimals.

    Built straight from the unscaled integers (no per-value Python work), so writing
    a vendor-style fixed-point CSV costs about as much as writing integers.
    """
    ints = np.rint(np.asarray(values, dtype=np.float64) * 10.0**decimals).astype(np.int64)
    words = np.empty((ints.shape[0], 2), dtype=np.int64)
    words[:, 0] = ints
    words[:, 1] = np.where(ints < 0, -1, 0)
    return pa.Array.from_buffers(pa.decimal128(38, decimals), ints.shape[0],
                                 [None, pa.py_buffer(words.tobytes())])


LineHook = Callable[[list[bytes]], list[bytes]]


def assemble(preamble: Sequence[str], header_line: str, body: bytes,
              corrupt: LineHook | None) -> bytes:
    if corrupt is not None:
        lines = body.split(b"\n")
        trailing = lines[-1] == b""
        lines = corrupt(lines[:-1] if trailing else lines)
        body = b"\n".join(lines) + (b"\n" if trailing else b"")
    head = "".join(line + "\n" for line in (*preamble, header_line))
    return head.encode("utf-8") + body
