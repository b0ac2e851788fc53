"""Column names of a data file, for ``ofbe-session init``: the units they state and the x, y, z
triads they form.

Column names are taken apart into a base and a stated unit (``'Accel X (g)'`` → ``accel_x``,
``g``) and grouped into x, y, z triads of a kind (acceleration, angular rate, magnetic field,
gravity-free linear acceleration…) and a label that tells two of a kind apart (``acc1_x``,
``acc2_x``); the acceleration triads become the manifest's ``ax``, ``ay``, ``az``, and the
angular-rate triad of the same device its ``gx``, ``gy``, ``gz``. :func:`unit_of_text` also
reads the units of a unit row (:mod:`ofbe_data.io.detection._layout`). Pure functions of names:
:mod:`ofbe_data.io.detection` calls them. A case the names do not settle (two columns for one
axis, several candidate triads) raises :class:`~ofbe_data.io.detection.DetectionError`
naming the command-line flag that settles it, never a guess.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ofbe_data.io.detection._units import DetectionError

COLUMNS_FLAG = "--columns t=NAME,ax=NAME,ay=NAME,az=NAME"


def unit_of_text(text: str) -> str | None:
    """The unit a column name's suffix or parenthesised part names, or None.

    ``s``, ``ms``, ``us``, ``ns`` for time; ``g``, ``mg``, ``m/s2``, ``counts`` for
    acceleration; ``rad/s``, ``deg/s`` for angular rate; ``C``, ``K``, ``F`` for temperature. A
    character that was not UTF-8 (U+FFFD: a Windows code page's ``²``, ``°`` or ``µ``) is read as
    whichever of these makes a unit.
    """
    if "\ufffd" in text:
        return next((u for c in "²°µ" if (u := unit_of_text(text.replace("\ufffd", c))) is not None), None)
    raw = text.strip().lower().replace(" ", "").strip("[]()")
    gyro = {"rad/s": "rad/s", "rad/sec": "rad/s", "rads": "rad/s", "rad_s": "rad/s", "rad/s-1": "rad/s",
            "deg/s": "deg/s", "°/s": "deg/s", "dps": "deg/s", "degs": "deg/s", "deg_s": "deg/s",
            "deg/sec": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "°/sec": "deg/s",
            "rads^-1": "rad/s", "rads-1": "rad/s", "rad.s-1": "rad/s", "rad·s-1": "rad/s",
            "degs^-1": "deg/s", "degs-1": "deg/s", "°s^-1": "deg/s", "°s-1": "deg/s"}
    if raw in gyro:
        return gyro[raw]
    u = raw.replace("°", "").replace("deg", "")
    table = {
        "s": "s", "sec": "s", "secs": "s", "second": "s", "seconds": "s",
        "ms": "ms", "msec": "ms", "millis": "ms", "milliseconds": "ms",
        "us": "us", "µs": "us", "μs": "us", "usec": "us", "micros": "us", "microseconds": "us",
        "ns": "ns", "nsec": "ns", "nanos": "ns", "nanoseconds": "ns",
        "g": "g", "mg": "mg", "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts",
        "adc": "counts", "digits": "counts",
        "c": "C", "k": "K", "f": "F",
    }
    if u in table:
        return table[u]
    if re.fullmatch(r"m/?s(\^?2|²|-2|\*\*2)|mps2|m_s2|m_s_2|ms2|ms\^-2|m\.s-2|m/s/s", u):
        return "m/s2"
    return None


TIME_NAMES = {"t", "time", "times", "timestamp", "time_stamp", "tstamp", "ts", "seconds", "secs", "sec",
               "elapsed", "elapsed_time", "millis", "micros", "nanos", "epoch", "epoch_time", "unix_time",
               "unixtime", "clock", "host_time", "sensor_time", "device_time", "timer", "utc", "rel_time",
               "time_since_start", "relative_time", "timestamp_s", "time_s", "zeit", "tiempo", "tempo"}
INDEX_NAMES = {"n", "n_samples", "nsamples", "sample", "samples", "sample_index", "sample_no", "sample_nr",
                "sample_number", "sample_count", "sample_num", "index", "idx", "i", "count", "counter",
                "frame", "packet", "seq", "sequence", "record", "no", "nr", "num", "number"}
TEMP_NAMES = {"temp", "temperature", "die_temp", "chip_temp", "imu_temp", "sensor_temp", "board_temp"}
_UNIT_SUFFIX = re.compile(r"^(?P<base>.+?)_(?P<unit>s|sec|secs|ms|msec|us|usec|ns|nsec|g|mg|ms2|mps2|m_s2|"
                          r"raw|counts|lsb|c|degc|k|f|dps|rads|rad_s|degs|deg_s)$")

# What a triad's word says it measures. Order matters: a longer or more specific word first
# ("linear acceleration" is gravity-free, not the specific force; "rotation rate" is a gyroscope).
_KIND_WORDS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("linacc", ("linearacceleration", "linearaccel", "linacc", "useracceleration", "useraccel", "lacc")),
    ("gravity", ("gravity", "grav")),
    ("gyro", ("gyroscope", "gyrorotation", "rotationrate", "angularvelocity", "angularrate", "gyro", "gyr",
              "omega", "drehrate")),
    ("mag", ("magneticfield", "magnetometer", "magnet", "magn", "mag")),
    ("other", ("orientation", "quaternion", "euler", "angles", "angle", "attitude", "position", "velocity",
               "rotation", "tilt", "incl", "quat", "pos", "vel", "rot", "ori", "accuracy")),
    ("acc", ("accelerometeracceleration", "accelerometer", "acceleration", "beschleunigung", "beschl",
             "accel", "accl", "acc", "gforce", "gf")),
)
_LETTER_KIND = {"a": "acc", "g": "gyro", "w": "gyro", "m": "mag"}
_NOISE_WORDS = ("sensor", "values", "value", "imu", "raw", "data", "axis", "chip", "meas", "dev")
TRIAD_KINDS = ("acc", "gyro", "mag", "linacc", "gravity", "other", "bare", "unknown")
"""``acc``: the specific force; ``bare``: x, y, z alone; ``unknown``: a word that names no
quantity (``sensor_0``…); the others are recognised and never taken for the acceleration."""


@dataclass(frozen=True)
class ColumnName:
    """A column name taken apart: ``'Accel X (g)'`` → base ``accel_x``, unit ``g``."""

    raw: str
    base: str
    unit: str | None

    @property
    def compact(self) -> str:
        """The base without separators (``accel_x`` → ``accelx``)."""
        return self.base.replace("_", "")


def _classify(word: str) -> tuple[str, str]:
    """What a triad's word (letters and digits, no separators) measures, and what is left of it
    (the label that tells two triads of one kind apart: ``acc1`` → ``acc``, ``1``)."""
    digits = "".join(re.findall(r"\d+", word))
    letters = re.sub(r"\d+", "", word)
    for kind, words in _KIND_WORDS:
        for w in words:
            if w in letters:
                rest = letters.replace(w, "", 1)
                for noise in _NOISE_WORDS:
                    rest = rest.replace(noise, "")
                return kind, rest + digits
    stripped = letters
    for noise in _NOISE_WORDS:
        stripped = stripped.replace(noise, "")
    if stripped in _LETTER_KIND:
        return _LETTER_KIND[stripped], digits
    if not stripped:
        return "bare", digits
    return "unknown", letters + digits


def parse_name(raw: str) -> ColumnName:
    """Lower-case base (blanks and punctuation as ``_``) and the unit it states, if any.

    A bracketed part is the unit when it names one (``(g)``, ``[m/s^2]``); an index in brackets
    stays in the base (``accel[0]`` → ``accel_0``).
    """
    text, unit = raw, None
    m = re.match(r"^(.*?)\s*[(\[](.+?)[)\]]\s*$", text)
    if m and not m.group(2).strip().isdigit():
        text, unit = m.group(1), unit_of_text(m.group(2))
    base = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")
    if unit is None:
        s = _UNIT_SUFFIX.match(base)
        if s:
            stem, said = s.group("base"), unit_of_text(s.group("unit").replace("degc", "c").replace("m_s2",
                                                                                                  "m/s2"))
            if said is not None and (stem in TIME_NAMES | INDEX_NAMES | TEMP_NAMES
                                     or _triad_member(stem) is not None):
                base, unit = stem, said
    if unit is None and base in ("millis", "micros", "nanos"):
        unit = unit_of_text(base)
    return ColumnName(raw, base, unit)


def _triad_member(base: str) -> tuple[str, str, str, str] | None:
    """(kind, label, axis, form) of a column whose name ends (or starts) with an axis letter, or
    None. Digit axes (``acc_0``) need the other columns and are found by :func:`find_triads`."""
    c = base.replace("_", "")
    if not c or base in TIME_NAMES | INDEX_NAMES | TEMP_NAMES:
        return None
    m = re.fullmatch(r"(?P<pre>[a-z0-9]*?)(?P<ax>[xyz])(?P<post>\d*)", c)
    if m:
        kind, label = _classify(m.group("pre") + m.group("post"))
        return kind, label, m.group("ax"), "letters"
    m = re.fullmatch(r"(?P<ax>[xyz])(?P<post>[a-z][a-z0-9]*)", c)
    if m:
        kind, label = _classify(m.group("post"))
        if kind in ("acc", "gyro", "mag", "linacc"):
            return kind, label, m.group("ax"), "letters"
    return None


@dataclass(frozen=True)
class Triad:
    """Three columns that hold one vector quantity's x, y and z.

    Attributes
    ----------
    kind
        One of :data:`TRIAD_KINDS`.
    label
        What tells it apart from other triads of its kind (``1`` for ``acc1_x``), or ``''``.
    cols
        0-based column of ``x``, ``y`` and ``z``.
    unit
        The unit the three names state alike, or None.
    how
        ``letters`` (x, y, z in the names), ``digits`` (``_0, _1, _2``) or ``position``.
    """

    kind: str
    label: str
    cols: dict[str, int]
    unit: str | None
    how: str

    def names(self, names: list[ColumnName]) -> str:
        """The three column names (or indices), for evidence."""
        if not names:
            return ", ".join(f"column {i}" for i in self.cols.values())
        return ", ".join(repr(names[i].raw) for i in self.cols.values())


def find_triads(path: str | Path, names: list[ColumnName], numeric: list[int]) -> list[Triad]:
    """Every complete x, y, z triad among the numeric columns, by name.

    Names ending (or starting) with an axis letter (``ax``, ``ACCEL_X``, ``acc1_x``, ``x (g)``,
    ``gFx``) form a triad per (kind, label); names that differ only in a final digit 0, 1, 2
    (or 1, 2, 3) form one in that order (``acc_0``, ``acc_1``, ``acc_2``; ``accel[0]``…).

    Raises
    ------
    DetectionError
        Two columns of one triad name the same axis.
    """
    groups: dict[tuple[str, str], dict[str, list[int]]] = {}
    how: dict[tuple[str, str], str] = {}
    used: set[int] = set()
    for i in numeric:
        member = _triad_member(names[i].base)
        if member is None:
            continue
        kind, label, axis, form = member
        groups.setdefault((kind, label), {}).setdefault(axis, []).append(i)
        how[(kind, label)] = form
        used.add(i)
    digit_groups: dict[str, dict[int, int]] = {}
    for i in numeric:
        if i in used or names[i].base in TIME_NAMES | INDEX_NAMES | TEMP_NAMES:
            continue
        m = re.fullmatch(r"(.+)_([0-3])", names[i].base) or re.fullmatch(r"(.*[a-z])([0-3])", names[i].base)
        if m:
            digit_groups.setdefault(m.group(1), {})[int(m.group(2))] = i
    for stem, by_digit in digit_groups.items():
        first = min(by_digit)
        if set(by_digit) not in ({0, 1, 2}, {1, 2, 3}):
            continue
        kind, label = _classify(stem.replace("_", ""))
        key = (kind, label)
        if key in groups:
            continue
        groups[key] = {a: [by_digit[first + k]] for k, a in enumerate("xyz")}
        how[key] = "digits"
    out: list[Triad] = []
    for (kind, label), axes in groups.items():
        if set(axes) != {"x", "y", "z"}:
            continue
        twice = [a for a in "xyz" if len(axes[a]) > 1]
        if twice and kind in ("acc", "bare"):
            listed = ", ".join(repr(names[i].raw) for i in axes[twice[0]])
            raise DetectionError(path, f"two columns for the {kind} {twice[0]} axis ({listed})",
                                 COLUMNS_FLAG)
        if twice:
            continue
        cols = {a: axes[a][0] for a in "xyz"}
        units = {names[i].unit for i in cols.values()}
        unit = units.pop() if len(units) == 1 else None
        form = how[(kind, label)]
        if kind in ("bare", "unknown") and unit in ("g", "mg", "m/s2"):
            kind = "acc"  # the unit says what the word does not (EuRoC's a_RS_S_x [m s^-2])
        elif kind in ("bare", "unknown") and unit in ("rad/s", "deg/s"):
            kind = "gyro"
        out.append(Triad(kind, label, cols, unit, form))
    out.sort(key=lambda tr: min(tr.cols.values()))
    return out


def acceleration_triads(path: str | Path, names: list[ColumnName], triads: list[Triad]) -> tuple[
        list[Triad], str]:
    """The triads that hold the specific force, and why.

    Triads named for acceleration win; else a bare x, y, z; else the only triad whose word names
    no quantity (``sensor_0…``). Gravity-free linear acceleration, gravity, angular rate and
    magnetic field are never taken.

    Raises
    ------
    DetectionError
        No triad holds the specific force, or several candidates with nothing to choose.
    """
    acc = [tr for tr in triads if tr.kind == "acc"]
    if acc:
        return acc, "names " + "; ".join(tr.names(names) for tr in acc)
    for kind, why in (("bare", "x, y, z names"), ("unknown", "the only x/y/z triad of the file")):
        cands = [tr for tr in triads if tr.kind == kind]
        if len(cands) == 1:
            return cands, f"names {cands[0].names(names)} ({why})"
        if len(cands) > 1:
            listed = "; ".join(tr.names(names) for tr in cands)
            raise DetectionError(path, f"acceleration columns by name: {len(cands)} sets ({listed})",
                                 COLUMNS_FLAG)
    lin = [tr for tr in triads if tr.kind == "linacc"]
    if lin:
        raise DetectionError(path, f"only gravity-free linear acceleration ({lin[0].names(names)}), not the "
                                   "specific force labelling needs", COLUMNS_FLAG)
    raise DetectionError(path, "acceleration columns by name: 0 sets (none)",
                         COLUMNS_FLAG)


def gyro_triad_for(acc: Triad, accs: list[Triad], triads: list[Triad]) -> Triad | None:
    """The angular-rate triad of the same device as ``acc``: the gyroscope triad with its label,
    else the only one when the file has one accelerometer triad."""
    gyros = [tr for tr in triads if tr.kind == "gyro"]
    same = [tr for tr in gyros if tr.label == acc.label]
    if len(same) == 1:
        return same[0]
    if len(accs) == 1 and len(gyros) == 1:
        return gyros[0]
    return None


def is_time_name(name: ColumnName) -> bool:
    """A name that says time (``t``, ``Time (s)``, ``timestamp_ns``, ``accelerometerTimestamp…``)."""
    c = name.compact
    return name.base in TIME_NAMES or "timestamp" in c or c.endswith("time")
