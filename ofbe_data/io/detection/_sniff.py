"""What a data file is, from the file alone: its format, and for a generic csv every key of its
manifest entry (raw-formats.md, "Generic csv"), each decision with its evidence.

:func:`sniff_text` is what ``ofbe-session init`` runs on every file of a session folder. The
format comes from the A5 A5 sync bytes of an MSCIP binary stream, or from the signature line of
a registered text format (each format's sniffer, :func:`ofbe_data.io.formats.formats`:
``# ofbe-logger``, the MSCIP export's lines); any other text file is a generic csv whose
delimiter, preamble, comment
prefix, column line and unit row are found by :mod:`ofbe_data.io.detection._layout`, whose columns
are found from their names (:mod:`ofbe_data.io.detection._names`) or, without names, their positions
and values (:mod:`ofbe_data.io.detection._columns`), and whose time unit and rate
(:mod:`ofbe_data.io.detection._time`) and acceleration and angular-rate units
(:mod:`ofbe_data.io.detection._units`) are found from the numbers. A file with two accelerometer
triads gives two parts, one per device. Nothing is guessed: a case the file does not settle
raises :class:`~ofbe_data.io.detection.DetectionError` naming the flag that settles it.
Finally the file is read back through the detected entry with the reader ``ofbe-session check``
uses, and the rate reported is the one check reports. What the command line says and what is
found are :class:`~ofbe_data.io.detection.Hints` and
:class:`~ofbe_data.io.detection.Detection`. Reading only, never writing.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.detection._banner import read_banner
from ofbe_data.io.detection._columns import (
    choose_time_column,
    column_names,
    given_parts,
    named_parts,
    positional_parts,
)
from ofbe_data.io.detection._layout import (
    LAYOUT_LINES,
    MAX_DATA_LINES,
    Layout,
    TextLines,
    find_layout,
    read_numbers,
)
from ofbe_data.io.detection._names import TEMP_NAMES, ColumnName, parse_name
from ofbe_data.io.detection._result import Decision, Detection, Hints, Part
from ofbe_data.io.detection._time import (
    TIME_SCALE,
    decide_time_unit,
    lost_precision,
    preamble_rate,
    stamp_texts,
    step_stats,
)
from ofbe_data.io.detection._units import (
    DetectionError,
    decide_acc_unit,
    decide_gyro_unit,
    decide_temperature_unit,
    fmt_num,
)
from ofbe_data.io.device_options import BinOptions
from ofbe_data.io.formats import formats, read_device_file
from ofbe_data.io.formats.filebytes import MAX_FILE_BYTES, is_blank, read_file_bytes
from ofbe_data.io.formats.mscip_bin import decode_mscip
from ofbe_data.io.manifest import CsvMapping, DeviceSpec

SYNC = b"\xa5\xa5"
_TEXT_BYTES = frozenset(range(32, 127)) | {9, 10, 12, 13}


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
    rate: float | None = None
    if stream.seconds is not None and stream.n > 1:
        st = step_stats(np.asarray(stream.seconds, dtype=np.float64))
        rate = 1.0 / st.median if st.median > 0 else None
        det.step_note = (f"time sub-packets (0x88): median step {fmt_num(st.median)} s → "
                         f"{fmt_num(rate or 0.0, 5)} Hz")
        if hints.rate_hz is not None:
            det.options["sample_rate_hz"] = hints.rate_hz
            det.add("sample_rate_hz", hints.rate_hz, "given with --rate (nominal)")
    elif hints.rate_hz is not None:
        det.options["sample_rate_hz"] = rate = hints.rate_hz
        det.add("sample_rate_hz", hints.rate_hz, "given with --rate; no time sub-packets")
    else:
        raise DetectionError(path, "an MSCIP stream without time sub-packets (0x88)", "--rate HZ")
    window = int(round(rate)) if rate and rate > 10 else 100
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


def _known_text(path: Path, lines: Sequence[str]) -> Detection | None:
    """The registered text format whose signature line comes first in the file's first 300 lines
    (:attr:`~ofbe_data.io.formats.Format.sniff`), or None."""
    sniffers = [f for f in formats() if f.sniff is not None]
    for i in range(min(len(lines), 300)):
        for fmt in sniffers:
            assert fmt.sniff is not None
            found = fmt.sniff(lines, i)
            if found is None:
                continue
            det = Detection(path, fmt.name)
            det.add("format", fmt.name, found.evidence)
            if found.model:
                det.model = found.model
                det.add("model", found.model, found.model_evidence)
            if found.rate_note:
                det.step_note = found.rate_note
            return det
    return None


def _generic_evidence() -> str:
    """Why a text file is a generic csv: none of the registered formats' signatures."""
    signatures = [f.signature for f in formats() if f.signature]
    return "no " + " and no ".join(signatures) + ": a generic csv"


# --------------------------------------------------------------------------- generic csv


def _time(path: Path, lines: list[str], data: np.ndarray, base: dict[int, int], lay: Layout,
          names: list[ColumnName], t: int | None, kind: str, hints: Hints, det: Detection
          ) -> tuple[str, float | None, str]:
    """``time_unit``, ``sample_rate_hz`` (None: not written) and the steps' evidence; records the
    decisions. Without a time column the rate must be given or stated in the file."""
    pre = preamble_rate(lines[:lay.column_line])
    if pre is None and lay.comment:
        pre = preamble_rate([line for line in lines[:LAYOUT_LINES] if line.startswith(lay.comment)])
    rate = hints.rate_hz
    rate_why = "given with --rate"
    if rate is None and pre is not None:
        rate, rate_why = pre[0], f"stated in the preamble, {pre[1]}"
    if t is None:
        if rate is None:
            raise DetectionError(path, "no time column and no sample rate in the file", "--rate HZ")
        det.add("sample_rate_hz", rate, rate_why + "; no time column")
        return "s", rate, f"{rate_why}; each data line is the next sample"
    tname = f"{names[t].raw!r}" if names else f"column {t}"
    if names and lay.unit_row is not None and names[t].unit and parse_name(names[t].raw).unit is None:
        tname += f" (its unit in line {lay.unit_row + 1})"
    first = base.get(t)
    stamps = stamp_texts(lines, lay, t)
    td = decide_time_unit(path, data[:, t], tname, names[t].unit if names else None, kind, hints.time_unit,
                          None if first is None else float(first), stamps)
    lost = None if td.unit == "samples" else lost_precision(stamps, data[:, t], t in base)
    lost_note = f"; {lost.note(td.unit)}" if lost is not None else ""  # the time unit's and rate's evidence
    det.add("time_unit", td.unit, td.evidence + lost_note)
    if td.warning:
        det.warnings.append(td.warning)
    if lost is not None:
        det.warnings.append(lost.warning(tname, td.unit, td.rate_hz))
    if td.unit == "samples":
        if rate is None:
            raise DetectionError(path, f"{tname} is a sample index and the file states no rate", "--rate HZ")
        det.add("sample_rate_hz", rate, rate_why)
        return "samples", rate, f"{rate_why}; {tname} counts the samples"
    if rate is not None:
        det.add("sample_rate_hz", rate, rate_why + " (nominal; the rate is measured from t)")
        assert td.rate_hz is not None
        if abs(td.rate_hz / rate - 1.0) > 0.02:
            det.warnings.append(f"the measured rate {fmt_num(td.rate_hz)} Hz is "
                                f"{100 * (td.rate_hz / rate - 1):+.3g} % from the nominal {fmt_num(rate)} Hz")
        return td.unit, rate, td.rate_evidence() + lost_note
    return td.unit, None, td.rate_evidence() + lost_note


def _by_index(lines: list[str], lay: Layout, det: Detection) -> bool:
    """Whether the column line (or the unit row) is not UTF-8 text (a Windows code page's ``°`` or
    ``²``), which the reader cannot take for a column line: then the names decide here and the
    manifest skips them and names the columns by index (the decisions are rewritten to say so)."""
    rows = [i for i in (lay.header_line, lay.unit_row) if i is not None]
    if not lay.names or not any("\ufffd" in lines[i] for i in rows):
        return False
    last = max(rows)
    unit_comment = lay.unit_row is not None and lay.comment == lines[lay.unit_row]
    drop = {"header", "skip_rows"} | ({"comment"} if unit_comment else set())
    at = next(k for k, d in enumerate(det.decisions) if d.key == "header")
    det.decisions = [d for d in det.decisions if d.key not in drop]
    why = (f"line {(lay.header_line or 0) + 1} holds the column names but is not UTF-8 text (a Windows code "
           "page?), which the reader takes for no column line: the names decide here, the manifest names the "
           "columns by index")
    det.decisions[at:at] = [Decision("header", False, why),
                            Decision("skip_rows", last + 1, f"line{'s 1–' if last else ' '}{last + 1}: up to "
                                     + ("the unit row" if lay.unit_row is not None else "the column line"))]
    return True


def _sniff_csv(path: Path, lines: list[str], hints: Hints) -> Detection:
    det = Detection(path, "csv")
    det.add("format", "csv", _generic_evidence())
    lay, found, warnings = find_layout(path, lines)
    for key, value, why in found:
        det.add(key, value, why)
    det.warnings.extend(warnings)
    banner = read_banner(lines, lay.data_start)
    if banner.model is not None:
        det.model = banner.model
        det.add("model", banner.model, f"line {banner.model_line}: "
                                       f"{lines[banner.model_line - 1].strip()[:60]!r}")
    if banner.range_g is not None:
        det.add("range_g", banner.range_g, f"line {banner.range_line}: "
                                           f"{lines[banner.range_line - 1].strip()[:60]!r}")
    data, parsed, base = read_numbers(lines, lay)
    if data.shape[0] < 10:
        raise RawFormatError(path, "at least 10 data lines", f"{data.shape[0]}", lay.data_start + 1)
    det.rows = int(data.shape[0])
    det.add("rows", det.rows, f"data lines from line {lay.data_start + 1}"
                              + (f"; {parsed - det.rows} unreadable" if parsed > det.rows else "")
                              + ("; only the first lines were read" if parsed >= MAX_DATA_LINES else ""))
    names = column_names(lay)
    skip_rows, header, comment = lay.skip_rows, bool(lay.names), lay.comment
    by_index = _by_index(lines, lay, det)
    if by_index:
        skip_rows, header = max(lay.column_line, lay.unit_row or 0) + 1, False
        comment = None if lay.unit_row is not None and comment == lines[lay.unit_row] else comment
    temps = [i for i, n in enumerate(names) if n.base in TEMP_NAMES and i in lay.numeric]
    temp = temps[0] if len(temps) == 1 else None
    if hints.columns:
        parts, t, kind, temp = given_parts(path, lay, names, hints)
        t_why = ""
    elif names:
        parts, axes = named_parts(path, names, lay)
        t, kind, t_why = choose_time_column(path, data, lay, names, axes, hints, parts[0].acc)
    else:
        t, kind, t_why = choose_time_column(path, data, lay, [], set(), hints, [])
        parts = positional_parts(path, data, lay, t)
    time_unit, rate, det.step_note = _time(path, lines, data, base, lay, names, t, kind, hints, det)
    median = step_stats(data[:, t]).median if t is not None and time_unit != "samples" else 0.0
    fs = (1.0 / (median * TIME_SCALE[time_unit]) if median > 0 else rate) or 100.0
    window = int(round(fs)) if fs > 10 else 100
    temp_unit = names[temp].unit if temp is not None and names else None
    temp_unit = temp_unit if temp_unit in ("C", "K", "F") else None
    td = None  # a unit the values contradict, or that no unit settles: the column is left unmapped
    if temp is not None:
        td = decide_temperature_unit(data[:, temp], temp_unit, names[temp].raw if names else str(temp))
        temp, temp_unit = (temp, td.unit) if td.unit is not None else (None, None)

    def key_of(i: int) -> str | int:
        return names[i].raw if names and not by_index else i

    for p in parts:
        label = p.label or None
        cols: dict[str, str | int] = {}
        why = p.why
        if t is not None:
            cols["t"] = key_of(t)
            if t_why:
                why = (f"t={names[t].raw!r}" if names else f"t=column {t}") + f" ({t_why}); " + why
        cols.update({k: key_of(i) for k, i in zip(("ax", "ay", "az"), p.acc, strict=True)})
        if temp is not None:
            cols["temperature"] = key_of(temp)
            if not hints.columns:
                why += f"; temperature={names[temp].raw!r}"
        gyro_unit = "rad/s"
        if p.gyro:
            unit, gwhy = decide_gyro_unit(data[:, p.gyro], p.gyro_unit, hints.gyro_unit)
            if unit is not None:
                cols.update({k: key_of(i) for k, i in zip(("gx", "gy", "gz"), p.gyro, strict=True)})
                gyro_unit = unit
                why += f"; {p.gyro_why}"
                det.add("columns", cols, why, label)
                det.add("gyro_unit", unit, gwhy, label)
            else:
                if hints.columns and "gx" in hints.columns:
                    raise DetectionError(path, f"the angular-rate columns given with --columns: {gwhy}",
                                         "--gyro-unit rad/s or deg/s")
                det.add("columns", cols, why, label)
                det.add("gyro", "not mapped", f"{p.gyro_why}; {gwhy}", label)
        else:
            det.add("columns", cols, why, label)
        acc = data[:, p.acc]
        by_row = bool(names) and lay.unit_row is not None and all(parse_name(names[i].raw).unit is None
                                                                  for i in p.acc)
        stated_by = (f"the unit row (line {(lay.unit_row or 0) + 1}) says" if by_row else
                     "the column names say")
        ad = decide_acc_unit(path, acc, window, p.acc_unit, hints.acc_unit, hints.lsb_per_g,
                             hints.zero_counts, stated_by)
        det.add("acc_unit", ad.unit, ad.evidence, label)
        if ad.unit == "counts":
            det.add("lsb_per_g", ad.lsb_per_g, ad.lsb_evidence, label)
            if np.any(np.asarray(ad.zero_counts, dtype=np.float64)):
                det.add("zero_counts", ad.zero_counts, ad.zero_evidence, label)
            else:
                det.add("zero", 0, ad.zero_evidence, label)
        det.warnings.extend(ad.warnings)
        mapping = CsvMapping(
            columns=cols, time_unit=time_unit, acc_unit=ad.unit, lsb_per_g=ad.lsb_per_g,
            skip_rows=skip_rows, delimiter=lay.delimiter, header=header, comment=comment,
            sample_rate_hz=rate, zero_counts=ad.zero_counts, range_g=banner.range_g,
            temperature_unit=(temp_unit or "C") if "temperature" in cols else "C", gyro_unit=gyro_unit)
        det.parts.append(Part(p.label, mapping, ad.direction))
    if td is not None:
        det.warnings.extend([td.warning] if td.warning else [])
        if td.unit is None:
            det.add("temperature", "not mapped", td.evidence)
        elif td.unit != "C":
            det.add("temperature_unit", td.unit, td.evidence)
    det.mapping, det.direction = det.parts[0].mapping, det.parts[0].direction
    return det


# --------------------------------------------------------------------------- the rate check reports


def _read_back(det: Detection) -> None:
    """Read the file through the detected entry with the reader ``check`` uses (a detection
    mistake stops here, before a manifest is written) and record the rate as check reports it."""
    if det.format == "csv":
        specs = [DeviceSpec("probe", "unknown", "dut", "csv", csv=p.mapping) for p in det.parts]
    elif det.format == "mscip-bin":
        specs = [DeviceSpec("probe", "unknown", "dut", "mscip-bin", bin=BinOptions(**det.options))]
    else:
        specs = [DeviceSpec("probe", "unknown", "dut", det.format)]
    recs = [read_device_file(det.path, spec) for spec in specs]
    rec = recs[0]
    det.rate_hz = rec.fs_hz
    missing = rec.diagnostics.missing_samples
    span = float(rec.t[-1] - rec.t[0])
    why = (f"the mean rate, as check reports it: ({rec.n} samples − 1 + {missing} missing in gaps) / "
           f"{fmt_num(span, 6)} s")
    if det.step_note:
        why += f"; {det.step_note}"
    det.add("rate", f"{fmt_num(rec.fs_hz, 5)} Hz", why)


def sniff_text(path: str | Path, hints: Hints = Hints()) -> Detection:  # noqa: B008 (Hints is frozen)
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
        if path.stat().st_size > MAX_FILE_BYTES:  # refused before it is read (bounded memory)
            with open(path, "rb") as fh:
                head = fh.read(4096)
            read_file_bytes(path, text=b"\0" not in head)  # raises: a NUL-filled tail, or too large
        data = path.read_bytes()
    except OSError as exc:
        raise RawFormatError(path, "a readable file", exc.strerror or str(exc)) from None
    if is_blank(data):
        raise RawFormatError(path, "data lines", "an empty file")
    binary = _binary(path, data, hints)
    if binary is not None:
        del data  # the reader reads the file again: one copy at a time (bounded memory)
        _read_back(binary)
        return binary
    lines = TextLines(data)  # the lines, decoded one at a time: never the whole file as text
    det = _known_text(path, lines) or _sniff_csv(path, lines, hints)
    del data, lines
    _read_back(det)
    return det
