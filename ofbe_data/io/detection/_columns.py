"""Which columns of a generic csv file hold the time, the acceleration and the angular rate, for
:func:`ofbe_data.io.detection.sniff_text`.

With a column line the names decide (:mod:`ofbe_data.io.detection._names`): one part per
accelerometer triad, each with the angular-rate triad of its device. Without one, the
positions and values do: triads of numeric columns after the time column, a further
accelerometer reading 1 g as the first does, a triad whose mean at rest has no acceleration's
norm being the gyroscope. ``--columns`` and ``--time-column`` win over both. The time column
has a time name, else an index name, else it is the one column that increases monotonically.
A case the file does not settle raises :class:`~ofbe_data.io.detection.DetectionError`
naming the command-line flag that settles it, never a guess.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ofbe_data.io.detection._layout import Layout
from ofbe_data.io.detection._names import (
    INDEX_NAMES,
    TEMP_NAMES,
    ColumnName,
    acceleration_triads,
    find_triads,
    gyro_triad_for,
    is_time_name,
    parse_name,
)
from ofbe_data.io.detection._result import Hints
from ofbe_data.io.detection._units import UNIT_TOLERANCE, DetectionError, offset_binary_zero, quiet_mean
from ofbe_data.io.gravity import G0


def _monotonic(values: np.ndarray) -> bool:
    steps = np.diff(values)
    return steps.size > 0 and float(np.mean(steps > 0)) >= 0.99 and values[-1] > values[0]


def _is_index(values: np.ndarray) -> bool:
    return bool(np.all(values == np.round(values))) and float(np.median(np.diff(values))) == 1.0


def _shared_prefix(a: str, b: str) -> str:
    n = 0
    while n < min(len(a), len(b)) and a[n] == b[n]:
        n += 1
    return a[:n]


def choose_time_column(path: Path, data: np.ndarray, lay: Layout, names: list[ColumnName], axes: set[int],
                 hints: Hints, acc: list[int]) -> tuple[int | None, str, str]:
    """The time column (None: there is none), its kind (``time``, ``index``, ``values``) and why."""
    if hints.time_column is not None:
        want = hints.time_column
        idx = [i for i, n in enumerate(names) if n.raw == want] if names else (
            [int(want)] if want.isdigit() and int(want) < lay.width else [])
        if not idx:
            raise DetectionError(path, f"no column {want!r} (--time-column)", "--time-column NAME")
        i = idx[0]
        return i, ("time" if names and is_time_name(names[i]) else "values"), "given with --time-column"
    if names:
        timed = [i for i, n in enumerate(names) if is_time_name(n) and i in lay.numeric and i not in axes]
        index = [i for i, n in enumerate(names) if n.base in INDEX_NAMES and i in lay.numeric]
        if len(timed) > 1:
            # one time column per sensor (iOS SensorLog): the one named like the acceleration columns
            shared = {i: max((_shared_prefix(names[i].compact, names[a].compact) for a in acc), key=len)
                      for i in timed}
            near = [i for i in timed if len(shared[i]) >= 4]
            if len(near) == 1:
                return near[0], "time", (f"a time name sharing {shared[near[0]]!r} with the acceleration "
                                         "columns")
            listed = ", ".join(repr(names[i].raw) for i in timed)
            raise DetectionError(path, f"two candidate time columns ({listed})", "--time-column NAME")
        if timed:
            return timed[0], "time", "a time name"
        if len(index) == 1:
            return index[0], "index", "an index name"
    cands = [c for c in lay.numeric if c not in axes and _monotonic(data[:, c])]
    if names:
        cands = [c for c in cands if names[c].base not in TEMP_NAMES]
    if len(cands) > 1:
        real = [c for c in cands if not _is_index(data[:, c])]
        if len(real) == 1:
            return real[0], "values", "increases monotonically"
        listed = ", ".join(repr(names[c].raw) if names else f"column {c}" for c in cands)
        raise DetectionError(path, f"two candidate time columns ({listed}, each increasing)",
                             "--time-column NAME" if names else "--time-column INDEX")
    return (cands[0], "values", "increases monotonically") if cands else (None, "", "")


@dataclass
class _PartColumns:
    """The columns of one accelerometer triad (and its gyroscope's) before units are decided."""

    label: str
    acc: list[int]
    acc_unit: str | None
    why: str
    gyro: list[int] = field(default_factory=list)
    gyro_unit: str | None = None
    gyro_why: str = ""


SAME_NORM = 0.03
"""Two accelerometers of one file read 1 g alike: their norms at rest within 3 %."""
STILL_NOISE = 0.05
"""At rest an accelerometer's noise (rms over the quietest block) is well below 5 % of its 1 g; a
gyroscope's reading at rest is its bias, whose noise is a large part of it."""


def _acceleration_unit(acc: np.ndarray) -> tuple[str | None, float]:
    """The unit in which the mean at rest of three columns has the norm of 1 g (``m/s2``, ``g``,
    ``mg``, ``counts 4096``, ``offset 32768``), or None: none does, or the reading is too noisy
    for an accelerometer at rest; and that norm (less the offset)."""
    mean, a, b = quiet_mean(acc, 100)
    norm = float(np.linalg.norm(mean))
    if not norm > 0 or float(np.sqrt(np.sum(np.var(acc[a:b], axis=0)))) > STILL_NOISE * norm:
        return None, norm
    ones = {"m/s2": G0, "g": 1.0, "mg": 1000.0}
    if bool(np.all(acc == np.round(acc))):
        zero = offset_binary_zero(acc, mean)
        if zero is not None:
            return f"offset {zero}", float(np.linalg.norm(mean - zero))
        ones.update({f"counts {2 ** k}": 2.0**k for k in range(5, 17)})
    return next((u for u, one in ones.items() if abs(np.log(norm / one)) <= UNIT_TOLERANCE), None), norm


def _labels(labels: list[str]) -> list[str]:
    """Part labels: the triads' own when they tell them apart, else 1, 2…; one part: ''."""
    if len(labels) == 1:
        return [""]
    clean = [re.sub(r"[^A-Za-z0-9._-]+", "-", x).strip("-") for x in labels]
    if all(clean) and len(set(clean)) == len(clean):
        return clean
    return [str(k + 1) for k in range(len(labels))]


def named_parts(path: Path, names: list[ColumnName], lay: Layout) -> tuple[list[_PartColumns], set[int]]:
    """Parts from the column names, and every column of a triad (never the time column)."""
    triads = find_triads(path, names, lay.numeric)
    accs, why = acceleration_triads(path, names, triads)
    labels = _labels([tr.label for tr in accs])
    parts = []
    for tr, label in zip(accs, labels, strict=True):
        gyro = gyro_triad_for(tr, accs, triads)
        how = {"digits": " (axes numbered 0, 1, 2)", "letters": "", "position": ""}[tr.how]
        part = _PartColumns(label, list(tr.cols.values()), tr.unit,
                            (f"names {tr.names(names)}{how}" if len(accs) > 1 else why + how))
        if gyro is not None:
            part.gyro, part.gyro_unit = list(gyro.cols.values()), gyro.unit
            part.gyro_why = f"angular rate: names {gyro.names(names)}"
        parts.append(part)
    if len(accs) > 1:
        parts[0].why += (f" (one of {len(accs)} accelerometer triads in the file: each is a device of its "
                         "own reading the same file)")
    return parts, {c for tr in triads for c in tr.cols.values()}


def positional_parts(path: Path, data: np.ndarray, lay: Layout, t: int | None) -> list[_PartColumns]:
    """Parts of a file without a column line: triads of numeric columns in order after the time
    column; a triad whose mean at rest has no acceleration's norm (near zero) is the gyroscope."""
    rest = [c for c in lay.numeric if c != t]
    after = [c for c in rest if t is None or c > t]
    pool = after if len(after) >= 3 else rest
    if len(pool) < 3:
        raise DetectionError(path, f"{len(pool)} numeric columns besides the time column, not three",
                             "--columns t=INDEX,ax=INDEX,ay=INDEX,az=INDEX")
    groups = [pool[k:k + 3] for k in range(0, len(pool) - 2, 3)]
    found = [_acceleration_unit(data[:, g]) for g in groups] if len(groups) > 1 else [("?", 1.0)]
    # a further accelerometer reads as the first does, in the same unit and within 3 % of its norm
    # (a gyroscope's bias may look like 1 g in some unit, hardly like the accelerometer's 1 g)
    first, norm = next(((u, n) for u, n in found if u is not None), (None, 0.0))
    fits = [u is not None and u == first and abs(n / norm - 1.0) <= SAME_NORM for u, n in found]
    accs = [g for g, ok in zip(groups, fits, strict=True) if ok] or groups[:1]
    gyro = next((g for g in groups if g not in accs), None) if len(groups) == 2 and len(accs) == 1 else None
    used = [c for g in accs for c in g] + (gyro or [])
    extra = [c for c in rest if c not in used]
    where = "after t" if pool == after and t is not None else "left"
    parts = []
    for k, g in enumerate(accs):
        why = f"by position: columns {g[0]}, {g[1]}, {g[2]}"
        if k == 0:
            why += f" are the first three numeric columns {where}"
        if len(groups) > 1:
            why += (f" (their mean at rest has the norm of 1 g in {first})" if fits[groups.index(g)] else
                    " (no triad's mean at rest has the norm of 1 g in a unit)")
        if k == len(accs) - 1 and extra:
            why += f" (column{'s' if len(extra) > 1 else ''} {', '.join(map(str, extra))} not used)"
        parts.append(_PartColumns(str(k + 1) if len(accs) > 1 else "", g, None, why))
    if gyro is not None:
        parts[0].gyro = gyro
        parts[0].gyro_why = (f"by position: columns {gyro[0]}, {gyro[1]}, {gyro[2]}, whose mean at rest has "
                             "no acceleration's norm (or a noisy one): angular rate")
    return parts


def given_parts(path: Path, lay: Layout, names: list[ColumnName], hints: Hints
                 ) -> tuple[list[_PartColumns], int | None, str, int | None]:
    """The one part ``--columns`` gives, its time column and kind, and its temperature column."""
    assert hints.columns is not None
    pos: dict[str, int] = {}
    for key, value in hints.columns.items():
        if names:
            raw = [n.raw for n in names]
            if value not in raw:
                raise DetectionError(path, f"no column {value!r} (--columns {key}=)",
                                     f"--columns with names from line {(lay.header_line or 0) + 1}")
            pos[key] = raw.index(value)
        elif value.isdigit() and int(value) < lay.width:
            pos[key] = int(value)
        else:
            raise DetectionError(path, f"no column index {value!r} among {lay.width} columns (--columns "
                                       f"{key}=; the file has no column line)",
                                 "--columns with 0-based indices")
    acc = [pos[k] for k in ("ax", "ay", "az")]
    units = {names[i].unit for i in acc} if names else set()
    part = _PartColumns("", acc, units.pop() if len(units) == 1 else None, "given with --columns")
    if all(k in pos for k in ("gx", "gy", "gz")):
        part.gyro = [pos[k] for k in ("gx", "gy", "gz")]
        gunits = {names[i].unit for i in part.gyro} if names else set()
        part.gyro_unit = gunits.pop() if len(gunits) == 1 else None
        part.gyro_why = "given with --columns"
    t = pos.get("t")
    kind = "time" if names and t is not None and is_time_name(names[t]) else "values"
    return [part], t, kind, pos.get("temperature")


def column_names(lay: Layout) -> list[ColumnName]:
    """The column names taken apart, with the units a unit row under them states."""
    names = [parse_name(n) for n in lay.names]
    if lay.units:
        names = [ColumnName(n.raw, n.base, n.unit or (lay.units[i] if i < len(lay.units) else None))
                 for i, n in enumerate(names)]
    return names
