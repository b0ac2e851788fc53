"""A calibration store: files filed by device and time, and the one in force at a given time.

imucal's ``cal_store`` idea (``save_calibration_info`` / ``find_closest_calibration_info_to_date``)
with ofbe's names: ``DIR/<device>/<device>_<YYYYmmddTHHMMSS[.ffffff]>.<ending>``, the time in UTC
to the microsecond (the fraction written only when not zero, trailing zeros dropped; the
recording's start where known, see :mod:`ofbe_data.calibration.results`) and the ending the
format's (:data:`ofbe_data.calibration.formats.FORMAT_EXTENSIONS`).

imucal-format files are filed the way imucal's own ``save_calibration_info`` names them, so
that its ``find_calibration_info_for_sensor`` and ``find_closest_calibration_info_to_date``
find them: ``DIR/<device>/<sensor_id>_<YYYY-mm-dd_HH-MM>.json`` with ``sensor_id`` the device
id lower-cased with everything but letters and digits removed (imucal requires alphanumeric
ids and splits the name at ``_``), the time in UTC to the minute (imucal's resolution). Unlike
imucal's search, :func:`find_calibration` never returns a calibration made after the time
asked about: the one in force is the latest at or before it.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime
from pathlib import Path

from ofbe_data.calibration.formats import FORMAT_EXTENSIONS
from ofbe_data.calibration.results import CalibrationExportError
from ofbe_data.io.manifest import ID_PATTERN

TIME_FORMAT = "%Y%m%dT%H%M%S"
"""Time stamp in store file names (UTC), followed by ``.ffffff`` when the time has a fraction."""
IMUCAL_TIME_FORMAT = "%Y-%m-%d_%H-%M"
"""Time stamp of imucal's store names (``save_calibration_info``; UTC here)."""
_STAMP = re.compile(r"(\d{8}T\d{6})(?:\.(\d{1,6}))?\.(.+)")
_IMUCAL_STAMP = re.compile(r"(\d{4}-\d{2}-\d{2}_\d{2}-\d{2})\.json")


class CalibrationStoreError(CalibrationExportError):
    """A store path or a look-up in a store is invalid."""


class CalibrationNotFoundError(CalibrationStoreError, LookupError):
    """The store holds no calibration of the device at or before the time asked about."""


def _utc(when: datetime) -> datetime:
    """Aware UTC datetime; a naive one is taken as UTC."""
    if not isinstance(when, datetime):
        raise CalibrationStoreError(f"when: expected a datetime, found {type(when).__name__}")
    return when.replace(tzinfo=UTC) if when.tzinfo is None else when.astimezone(UTC)


def _check_device(device: str) -> str:
    if not (isinstance(device, str) and ID_PATTERN.match(device)) or device in (".", ".."):
        raise CalibrationStoreError(f"device: expected an id of [A-Za-z0-9._-]+ (a file name), "
                                    f"found {device!r}")
    return device


def _ending(fmt: str) -> str:
    if fmt not in FORMAT_EXTENSIONS:
        raise CalibrationStoreError(f"format: expected one of {', '.join(FORMAT_EXTENSIONS)}, found {fmt!r}")
    return FORMAT_EXTENSIONS[fmt]


def imucal_sensor_id(device: str) -> str:
    """The sensor id an imucal-format file of ``device`` is filed under: the device id
    lower-cased, everything but ASCII letters and digits removed (``SparkFun-1`` → ``sparkfun1``).

    Raises
    ------
    CalibrationStoreError
        The id has no letter or digit.
    """
    sensor = re.sub(r"[^0-9a-z]", "", _check_device(device).lower())
    if not sensor:
        raise CalibrationStoreError(f"device {device!r}: expected at least one letter or digit for imucal's "
                                    "alphanumeric sensor id, found none")
    return sensor


def time_stamp(when: datetime) -> str:
    """``YYYYmmddTHHMMSS`` of ``when`` in UTC, then ``.`` and its fraction of a second (to the
    microsecond, trailing zeros dropped) when it has one."""
    at = _utc(when)
    stamp = at.strftime(TIME_FORMAT)
    return stamp if at.microsecond == 0 else stamp + "." + f"{at.microsecond:06d}".rstrip("0")


def store_path(store: str | Path, device: str, when: datetime, fmt: str) -> Path:
    """Where a calibration of ``device`` at ``when`` in format ``fmt`` is filed in ``store``.

    Returns
    -------
    Path
        ``store/<device>/<device>_<YYYYmmddTHHMMSS[.ffffff]>.<ending>`` (UTC); for ``imucal``
        ``store/<device>/<sensor_id>_<YYYY-mm-dd_HH-MM>.json`` (imucal's own layout, to the minute).
    """
    device = _check_device(device)
    if fmt == "imucal":
        name = f"{imucal_sensor_id(device)}_{_utc(when).strftime(IMUCAL_TIME_FORMAT)}.json"
        return Path(store) / device / name
    return Path(store) / device / f"{device}_{time_stamp(when)}.{_ending(fmt)}"


def _parse_name(name: str, device: str, by_ending: dict[str, str]) -> tuple[datetime, str] | None:
    """(time, format) of a store file name of ``device``, or None when it is not one."""
    prefix = f"{device}_"
    if name.startswith(prefix):
        m = _STAMP.fullmatch(name[len(prefix):])
        if m is not None and m.group(3) in by_ending:
            try:
                when = datetime.strptime(m.group(1), TIME_FORMAT).replace(tzinfo=UTC)
            except ValueError:
                return None
            fraction = m.group(2)
            if fraction:
                when = when.replace(microsecond=int(fraction.ljust(6, "0")))
            return when, by_ending[m.group(3)]
    try:
        sensor = f"{imucal_sensor_id(device)}_"
    except CalibrationStoreError:
        return None
    if name.startswith(sensor):
        m = _IMUCAL_STAMP.fullmatch(name[len(sensor):])
        if m is not None:
            try:
                return datetime.strptime(m.group(1), IMUCAL_TIME_FORMAT).replace(tzinfo=UTC), "imucal"
            except ValueError:
                return None
    return None


def stored_calibrations(store: str | Path, device: str, fmt: str | None = None
                        ) -> list[tuple[datetime, str, Path]]:
    """(time, format, path) of every calibration of ``device`` in ``store``, oldest first.

    Files whose names follow neither of the store's patterns are ignored (imucal files in ofbe's
    older layout, ``<device>_<stamp>.imucal.json``, are still found here, though not by imucal).
    """
    device = _check_device(device)
    folder = Path(store) / device
    by_ending = {v: k for k, v in FORMAT_EXTENSIONS.items()}
    if fmt is not None:
        _ending(fmt)
    found = []
    if folder.is_dir():
        for p in folder.iterdir():
            parsed = _parse_name(p.name, device, by_ending) if p.is_file() else None
            if parsed is None or (fmt is not None and parsed[1] != fmt):
                continue
            found.append((parsed[0], parsed[1], p))
    return sorted(found, key=lambda t: (t[0], t[1]))


def find_calibration(store: str | Path, device: str, when: datetime, fmt: str | None = None) -> Path:
    """The path of the device's latest calibration at or before ``when``.

    Parameters
    ----------
    store
        A store written by ``ofbe-export ... --store DIR``.
    device
        Device id.
    when
        The time of the recording to correct (a naive datetime is taken as UTC).
    fmt
        Only files of this format (``imucal``, ``kalibr``, ``ros``, ``ggir``, ``json``);
        None: any, as long as one file is the latest.

    Returns
    -------
    Path

    Raises
    ------
    CalibrationNotFoundError
        No calibration of the device in the store, or none at or before ``when``.
    CalibrationStoreError
        A bad device id, format or time, or (``fmt`` None) files of several formats share
        the latest time.
    """
    at = _utc(when)
    every = stored_calibrations(store, device, fmt)
    what = f"{device}{'' if fmt is None else f' ({fmt})'}"
    if not every:
        raise CalibrationNotFoundError(f"{store}: expected a calibration of {what} (files "
                                       f"{device}/{device}_<YYYYmmddTHHMMSS>.<ending>, or imucal's "
                                       f"{device}/<sensor_id>_<YYYY-mm-dd_HH-MM>.json), found none")
    before = [c for c in every if c[0] <= at]
    if not before:
        raise CalibrationNotFoundError(
            f"{store}: expected a calibration of {what} at or before {at.strftime('%Y-%m-%dT%H:%M:%SZ')}, "
            f"found only later ones (the earliest {every[0][0].strftime('%Y-%m-%dT%H:%M:%SZ')})")
    latest = [c for c in before if c[0] == before[-1][0]]
    if len(latest) > 1:
        raise CalibrationStoreError(f"{store}: {device}: files of several formats ("
                                    f"{', '.join(c[1] for c in latest)}) share the latest time; pass fmt")
    return latest[0][2]
