"""What a data file is, from the file alone: its format, and for a generic csv every key of its
manifest entry (raw-formats.md, "Generic csv"), each decision with its evidence.

:func:`sniff_text` is what ``ofbe-session init`` runs on every file of a session folder. The
format comes from the headers (``# ofbe-logger``; the MSCIP export's lines; A5 A5 sync bytes of
an MSCIP binary stream); any other text file is a generic csv whose delimiter, preamble, comment
prefix and column line are found by :mod:`ofbe_data.io.detect_layout`, whose columns are found
here, and whose time and acceleration units and rate are found from the numbers
(:mod:`ofbe_data.io.detect_units`). Nothing is guessed: a case the
file does not settle raises :class:`~ofbe_data.io.detect_units.DetectionError` naming the flag
that settles it. Reading only, never writing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.detect_layout import (
    LAYOUT_LINES,
    MAX_DATA_LINES,
    Layout,
    find_layout,
    read_numbers,
    split_lines,
)
from ofbe_data.io.detect_units import (
    INDEX_NAMES,
    TEMP_NAMES,
    TIME_NAMES,
    ColumnName,
    DetectionError,
    axis_columns,
    decide_acc_unit,
    decide_time_unit,
    fmt_num,
    parse_name,
    preamble_rate,
    step_stats,
)
from ofbe_data.io.formats.mscip_bin import decode_mscip
from ofbe_data.io.manifest import CsvMapping

SYNC = b"\xa5\xa5"
_TEXT_BYTES = frozenset(range(32, 127)) | {9, 10, 12, 13}


@dataclass(frozen=True)
class Hints:
    """What the command line says about a file (None: detect it).

    Attributes
    ----------
    rate_hz
        ``--rate``: the sample rate, Hz.
    acc_unit, lsb_per_g, zero_counts
        ``--unit``, ``--lsb-per-g``, ``--zero-counts``.
    time_unit
        ``--time-unit``.
    time_column
        ``--time-column``: the name (or index, without a header) of the time column.
    columns
        ``--columns``: every column key given (names, or indices without a header).
    """

    rate_hz: float | None = None
    acc_unit: str | None = None
    lsb_per_g: float | tuple[float, float, float] | None = None
    zero_counts: float | tuple[float, float, float] | None = None
    time_unit: str | None = None
    time_column: str | None = None
    columns: dict[str, str] | None = None


@dataclass(frozen=True)
class Decision:
    """One detected value and why.

    Attributes
    ----------
    key
        The manifest key it sets (``delimiter``, ``acc_unit``…) or a note's name (``rate``,
        ``rows``) when it sets none.
    value
        The value (as written in the manifest).
    evidence
        Why, in a few words a person can check.
    """

    key: str
    value: Any
    evidence: str

    def line(self) -> str:
        """``key: value (evidence)``."""
        return f"{self.key}: {show_value(self.value)} ({self.evidence})"


def show_value(value: Any) -> str:
    """A value as one short text (delimiters and comment prefixes quoted)."""
    if isinstance(value, str):
        return repr(value) if value in (",", ";", "\t", "#", "%", "//") else value
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {show_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return fmt_num(value, 6)
    return str(value)


@dataclass
class Detection:
    """What :func:`sniff_text` found in one file.

    Attributes
    ----------
    path
        The file.
    format
        ``ofbe-logger``, ``mscip-csv``, ``mscip-bin`` or ``csv``.
    decisions
        Every decision with its evidence, in the order made.
    mapping
        The manifest mapping (``csv`` only).
    options
        The manifest keys of an ``mscip-bin`` entry (``sample_rate_hz``, ``acc_unit``).
    model
        The device model a header names, or None.
    rate_hz
        Sample rate found, Hz, or None.
    rows
        Data rows read (for the statistics), or None.
    direction
        (3,) unit vector of the mean reading at rest, or None.
    warnings
        Things a person should look at.
    """

    path: Path
    format: str
    decisions: list[Decision] = field(default_factory=list)
    mapping: CsvMapping | None = None
    options: dict[str, Any] = field(default_factory=dict)
    model: str | None = None
    rate_hz: float | None = None
    rows: int | None = None
    direction: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)

    def add(self, key: str, value: Any, evidence: str) -> None:
        """Record a decision."""
        self.decisions.append(Decision(key, value, evidence))

    def evidence(self, key: str) -> str | None:
        """The evidence of the decision on ``key``, or None."""
        for d in self.decisions:
            if d.key == key:
                return d.evidence
        return None

    def lines(self) -> list[str]:
        """One line per decision."""
        return [d.line() for d in self.decisions]


# --------------------------------------------------------------------------- formats


def _binary(path: Path, data: bytes, hints: Hints) -> Detection | None:
    head = data[:65536]
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise RawFormatError(path, "UTF-8 or ASCII text (what the readers take)",
                             "UTF-16 text (byte-order mark FF FE or FE FF), which the readers do not take")
    odd = sum(1 for b in head if b not in _TEXT_BYTES and b < 128)
    if b"\x00" not in head and odd <= 0.05 * max(len(head), 1):
        return None
    stream = decode_mscip(data)
    if stream.n < 10:
        pairs = data.count(SYNC)
        raise RawFormatError(path, "a text data file or an MSCIP binary stream (A5 A5 sync bytes)",
                             f"binary data with {stream.n} valid MSCIP accelerometer packets ({pairs} A5 A5 "
                             "pairs)")
    det = Detection(path, "mscip-bin", model="MSCIP")
    det.rows = stream.n
    det.add("format", "mscip-bin", f"binary; {stream.packets_ok} valid MSCIP packets (A5 A5 sync, "
                                   f"checksums), {stream.n} with accelerometer data")
    det.add("rows", stream.n, f"IMU packets; {stream.bytes_skipped} bytes skipped")
    if stream.seconds is not None and stream.n > 1:
        st = step_stats(np.asarray(stream.seconds, dtype=np.float64))
        det.rate_hz = 1.0 / st.median if st.median > 0 else None
        det.add("rate", f"{fmt_num(det.rate_hz or 0.0, 6)} Hz", f"time sub-packets (0x88); median step "
                                                              f"{fmt_num(st.median)} s")
        if hints.rate_hz is not None:
            det.options["sample_rate_hz"] = hints.rate_hz
            det.add("sample_rate_hz", hints.rate_hz, "given with --rate (nominal)")
    elif hints.rate_hz is not None:
        det.options["sample_rate_hz"] = det.rate_hz = hints.rate_hz
        det.add("sample_rate_hz", hints.rate_hz, "given with --rate; no time sub-packets")
    else:
        raise DetectionError(path, "an MSCIP stream without time sub-packets (0x88)", "--rate HZ")
    window = int(round(det.rate_hz)) if det.rate_hz and det.rate_hz > 10 else 100
    unit = hints.acc_unit if hints.acc_unit != "counts" else None
    ad = decide_acc_unit(path, np.asarray(stream.acc, dtype=np.float64), window, None, unit)
    if ad.unit not in ("g", "mg", "m/s2"):
        raise DetectionError(path, f"MSCIP accelerometer values in {ad.unit} ({ad.evidence})",
                             "--unit g, mg or m/s2")
    if ad.unit != "g":
        det.options["acc_unit"] = ad.unit
    det.add("acc_unit", ad.unit, ad.evidence)
    det.direction = ad.direction
    det.warnings.extend(ad.warnings)
    return det


def _known_text(path: Path, lines: list[str]) -> Detection | None:
    for i, line in enumerate(lines[:300]):
        if line.startswith("# ofbe-logger"):
            det = Detection(path, "ofbe-logger")
            det.add("format", "ofbe-logger", f"'# ofbe-logger' header at line {i + 1}")
            keys = dict(tok.split("=", 1) for j in range(i, min(i + 10, len(lines)))
                        if lines[j].startswith("#") for tok in lines[j][1:].split() if "=" in tok)
            if keys.get("chip"):
                det.model = keys["chip"]
                det.add("model", keys["chip"], f"header chip={keys['chip']}")
            if keys.get("odr_hz"):
                det.add("rate", f"{keys['odr_hz']} Hz", f"header odr_hz={keys['odr_hz']} (nominal)")
            return det
        if line.strip() == "MSCIP Data Export" or line.startswith("Time (s),Gyro X (deg/s)"):
            det = Detection(path, "mscip-csv")
            det.add("format", "mscip-csv", f"MSCIP export line {i + 1}: {line.strip()[:40]!r}")
            for other in lines[i:i + 10]:
                key, _, value = other.partition(",")
                if key == "Device" and value.strip():
                    det.model = value.strip()
                    det.add("model", det.model, f"header line {other.strip()!r}")
                elif key == "Sample Rate (Hz)" and value.strip():
                    det.add("rate", f"{value.strip()} Hz", f"header line {other.strip()!r} (nominal)")
            return det
    return None


# --------------------------------------------------------------------------- columns

def _monotonic(values: np.ndarray) -> bool:
    steps = np.diff(values)
    return steps.size > 0 and float(np.mean(steps > 0)) >= 0.99 and values[-1] > values[0]


def _is_index(values: np.ndarray) -> bool:
    return bool(np.all(values == np.round(values))) and float(np.median(np.diff(values))) == 1.0


def _time_column(path: Path, data: np.ndarray, lay: Layout, names: list[ColumnName], axes: set[int],
                 hints: Hints) -> tuple[int | None, str]:
    """The time column (None: there is none) and its kind (``time``, ``index``, ``values``)."""
    if hints.time_column is not None:
        want = hints.time_column
        idx = [i for i, n in enumerate(names) if n.raw == want] if names else (
            [int(want)] if want.isdigit() and int(want) < lay.width else [])
        if not idx:
            raise DetectionError(path, f"no column {want!r} (--time-column)", "--time-column NAME")
        i = idx[0]
        return i, ("time" if names and names[i].base in TIME_NAMES else "values")
    if names:
        timed = [i for i, n in enumerate(names) if n.base in TIME_NAMES and i in lay.numeric]
        index = [i for i, n in enumerate(names) if n.base in INDEX_NAMES and i in lay.numeric]
        if len(timed) > 1:
            listed = ", ".join(repr(names[i].raw) for i in timed)
            raise DetectionError(path, f"two candidate time columns ({listed})", "--time-column NAME")
        if timed:
            return timed[0], "time"
        if len(index) == 1:
            return index[0], "index"
    cands = [c for c in lay.numeric if c not in axes and _monotonic(data[:, c])]
    if names:
        cands = [c for c in cands if names[c].base not in TEMP_NAMES]
    if len(cands) > 1:
        real = [c for c in cands if not _is_index(data[:, c])]
        if len(real) == 1:
            return real[0], "values"
        listed = ", ".join(repr(names[c].raw) if names else f"column {c}" for c in cands)
        raise DetectionError(path, f"two candidate time columns ({listed}, each increasing)",
                             "--time-column NAME" if names else "--time-column INDEX")
    return (cands[0], "values") if cands else (None, "")


def _columns(path: Path, data: np.ndarray, lay: Layout, hints: Hints, det: Detection
             ) -> tuple[dict[str, str | int], str | None, str, str | None]:
    """The ``columns`` mapping, the acceleration unit the names state, the time column's kind and
    the temperature unit."""
    names = [parse_name(n) for n in lay.names]
    key_of = (lambda i: names[i].raw) if names else (lambda i: i)
    if hints.columns:
        cols: dict[str, str | int] = {}
        for key, value in hints.columns.items():
            if names:
                if value not in [n.raw for n in names]:
                    raise DetectionError(path, f"no column {value!r} (--columns {key}=)",
                                         "--columns with names from line "
                                         f"{(lay.header_line or 0) + 1}")
                cols[key] = value
            elif value.isdigit() and int(value) < lay.width:
                cols[key] = int(value)
            else:
                raise DetectionError(path, f"no column index {value!r} among {lay.width} columns (--columns "
                                           f"{key}=; the file has no column line)", "--columns with 0-based "
                                                                                     "indices")
        det.add("columns", cols, "given with --columns")
        pos = {k: ([n.raw for n in names].index(v) if names else int(v)) for k, v in cols.items()}
        units = {names[pos[k]].unit for k in ("ax", "ay", "az") if names and k in pos}
        kind = "time" if names and "t" in pos and names[pos["t"]].base in TIME_NAMES else "values"
        t_unit = names[pos["temperature"]].unit if names and "temperature" in pos else None
        return cols, (units.pop() if len(units) == 1 else None), kind, t_unit
    if names:
        axes, acc_unit = axis_columns(path, names)
        why = "names " + ", ".join(f"{k}={names[i].raw!r}" for k, i in axes.items())
    else:
        axes, acc_unit, why = {}, None, ""
    t, kind = _time_column(path, data, lay, names, set(axes.values()), hints)
    if not names:
        rest = [c for c in lay.numeric if c != t]
        after = [c for c in rest if t is None or c > t]
        pick = after[:3] if len(after) >= 3 else rest[:3]
        axes = dict(zip(("ax", "ay", "az"), pick, strict=True))
        extra = [c for c in rest if c not in pick]
        why = (f"by position: columns {pick[0]}, {pick[1]}, {pick[2]} are the first three numeric columns "
               f"{'after t' if pick == after[:3] and t is not None else 'left'}"
               + (f" (column{'s' if len(extra) > 1 else ''} {', '.join(map(str, extra))} not used)"
                  if extra else ""))
    cols = {}
    if t is not None:
        cols["t"] = key_of(t)
        how = {"time": "a time name", "index": "an index name", "values": "increases monotonically"}[kind]
        why = (f"t={key_of(t)!r}" if names else f"t=column {t}") + f" ({how}); " + why
    temp_unit = None
    temps = [i for i, n in enumerate(names) if n.base in TEMP_NAMES and i in lay.numeric]
    cols.update({k: key_of(i) for k, i in axes.items()})
    if len(temps) == 1:
        cols["temperature"] = key_of(temps[0])
        temp_unit = names[temps[0]].unit if names[temps[0]].unit in ("C", "K", "F") else None
        why += f"; temperature={names[temps[0]].raw!r}"
    det.add("columns", cols, why)
    return cols, acc_unit, kind, temp_unit


def _sniff_csv(path: Path, lines: list[str], hints: Hints) -> Detection:
    det = Detection(path, "csv")
    det.add("format", "csv", "no '# ofbe-logger' header and no MSCIP export lines: a generic csv")
    lay, found, warnings = find_layout(path, lines)
    for key, value, why in found:
        det.add(key, value, why)
    det.warnings.extend(warnings)
    data, parsed, base = read_numbers(lines, lay)
    if data.shape[0] < 10:
        raise RawFormatError(path, "at least 10 data lines", f"{data.shape[0]}", lay.data_start + 1)
    det.rows = int(data.shape[0])
    det.add("rows", det.rows, f"data lines from line {lay.data_start + 1}"
                              + (f"; {parsed - det.rows} unreadable" if parsed > det.rows else "")
                              + ("; only the first lines were read" if parsed >= MAX_DATA_LINES else ""))
    cols, name_acc, kind, temp_unit = _columns(path, data, lay, hints, det)
    pos = {k: (lay.names.index(v) if lay.names else v) for k, v in cols.items()}
    pre = preamble_rate(lines[:lay.column_line])
    if pre is None and lay.comment:
        pre = preamble_rate([line for line in lines[:LAYOUT_LINES] if line.startswith(lay.comment)])
    rate = hints.rate_hz
    rate_why = "given with --rate"
    if rate is None and pre is not None:
        rate, rate_why = pre[0], f"stated in the preamble, {pre[1]}"
    time_unit = "s"
    if "t" in cols:
        tname = f"{cols['t']!r}" if lay.names else f"column {cols['t']}"
        unit = parse_name(str(cols["t"])).unit if lay.names else None
        first = base.get(int(pos["t"]))
        td = decide_time_unit(path, data[:, pos["t"]], tname, unit, kind, hints.time_unit,
                              None if first is None else float(first))
        time_unit = td.unit
        det.add("time_unit", td.unit, td.evidence)
        if td.unit == "samples":
            if rate is None:
                raise DetectionError(path, f"{tname} is a sample index and the file states no rate",
                                     "--rate HZ")
            det.add("sample_rate_hz", rate, rate_why)
            det.rate_hz = rate
        else:
            det.rate_hz = td.rate_hz
            if rate is not None:
                det.add("sample_rate_hz", rate, rate_why + " (nominal; the rate is measured from t)")
                assert td.rate_hz is not None
                if abs(td.rate_hz / rate - 1.0) > 0.02:
                    det.warnings.append(f"the measured rate {fmt_num(td.rate_hz)} Hz is "
                                        f"{100 * (td.rate_hz / rate - 1):+.3g} % from the nominal "
                                        f"{fmt_num(rate)} Hz")
        det.add("rate", f"{fmt_num(det.rate_hz or 0.0, 6)} Hz", td.rate_evidence())
    else:
        if rate is None:
            raise DetectionError(path, "no time column and no sample rate in the file", "--rate HZ")
        det.add("sample_rate_hz", rate, rate_why + "; no time column")
        det.rate_hz = rate
    window = int(round(det.rate_hz)) if det.rate_hz and det.rate_hz > 10 else 100
    acc = data[:, [pos["ax"], pos["ay"], pos["az"]]]
    ad = decide_acc_unit(path, acc, window, name_acc, hints.acc_unit, hints.lsb_per_g, hints.zero_counts)
    det.add("acc_unit", ad.unit, ad.evidence)
    if ad.unit == "counts":
        det.add("lsb_per_g", ad.lsb_per_g, ad.lsb_evidence)
        if np.any(np.asarray(ad.zero_counts, dtype=np.float64)):
            det.add("zero_counts", ad.zero_counts, ad.zero_evidence)
        else:
            det.add("zero", 0, ad.zero_evidence)
    det.direction = ad.direction
    det.warnings.extend(ad.warnings)
    if temp_unit is not None and temp_unit != "C":
        det.add("temperature_unit", temp_unit, "the column name says so")
    det.mapping = CsvMapping(
        columns=cols, time_unit=time_unit, acc_unit=ad.unit, lsb_per_g=ad.lsb_per_g,
        skip_rows=lay.skip_rows, delimiter=lay.delimiter, header=bool(lay.names), comment=lay.comment,
        sample_rate_hz=rate if det.evidence("sample_rate_hz") is not None else None,
        zero_counts=ad.zero_counts,
        temperature_unit=temp_unit or "C")
    return det


def sniff_text(path: str | Path, hints: Hints = Hints()) -> Detection:
    """What a data file is and, for a generic csv, how to read it, with the evidence.

    Parameters
    ----------
    path
        The file (read only).
    hints
        What the command line says (wins over detection).

    Returns
    -------
    Detection
        The format, every decision with its evidence and, for ``csv``, the manifest mapping.

    Raises
    ------
    DetectionError
        The file does not settle a key; the message names the flag to give.
    RawFormatError
        The file is no data file this toolkit reads (binary without MSCIP sync, no data lines,
        decimal commas).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RawFormatError(path, "a readable file", exc.strerror or str(exc)) from None
    if not data.strip():
        raise RawFormatError(path, "data lines", "an empty file")
    binary = _binary(path, data, hints)
    if binary is not None:
        return binary
    text = data.decode("utf-8", errors="replace")
    if text.startswith("\ufeff"):
        text = text[1:]
    lines = split_lines(text)
    return _known_text(path, lines) or _sniff_csv(path, lines, hints)
