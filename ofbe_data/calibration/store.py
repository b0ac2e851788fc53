"""A calibration store: files filed by device and time, and the one in force at a given time.

imucal's ``cal_store`` idea (``save_calibration_info`` / ``find_closest_calibration_info_to_date``)
with ofbe's names: ``DIR/<device>/<device>_<YYYYmmddTHHMMSS>.<ending>``, the time in UTC
(the recording's time where known, see :mod:`ofbe_data.calibration.results`) and the ending
the format's (:data:`ofbe_data.calibration.formats.FORMAT_EXTENSIONS`). Unlike imucal's
search, :func:`find_calibration` never returns a calibration made after the time asked
about: the one in force is the latest at or before it.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime
from pathlib import Path

from ofbe_data.calibration.formats import FORMAT_EXTENSIONS
from ofbe_data.calibration.results import CalibrationExportError
from ofbe_data.io.manifest import ID_PATTERN

TIME_FORMAT = "%Y%m%dT%H%M%S"
"""Time stamp in store file names (UTC)."""
_STAMP = re.compile(r"(\d{8}T\d{6})\.(.+)")


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


def store_path(store: str | Path, device: str, when: datetime, fmt: str) -> Path:
    """Where a calibration of ``device`` at ``when`` in format ``fmt`` is filed in ``store``.

    Returns
    -------
    Path
        ``store/<device>/<device>_<YYYYmmddTHHMMSS>.<ending>`` (UTC, whole seconds).
    """
    device = _check_device(device)
    stamp = _utc(when).strftime(TIME_FORMAT)
    return Path(store) / device / f"{device}_{stamp}.{_ending(fmt)}"


def stored_calibrations(store: str | Path, device: str, fmt: str | None = None
                        ) -> list[tuple[datetime, str, Path]]:
    """(time, format, path) of every calibration of ``device`` in ``store``, oldest first.

    Files whose names do not follow the store's pattern are ignored.
    """
    device = _check_device(device)
    folder = Path(store) / device
    by_ending = {v: k for k, v in FORMAT_EXTENSIONS.items()}
    wanted = None if fmt is None else _ending(fmt)
    found = []
    if folder.is_dir():
        prefix = f"{device}_"
        for p in folder.iterdir():
            if not (p.is_file() and p.name.startswith(prefix)):
                continue
            m = _STAMP.fullmatch(p.name[len(prefix):])
            if m is None or m.group(2) not in by_ending or (wanted is not None and m.group(2) != wanted):
                continue
            try:
                when = datetime.strptime(m.group(1), TIME_FORMAT).replace(tzinfo=UTC)
            except ValueError:
                continue
            found.append((when, by_ending[m.group(2)], p))
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
                                       f"{device}/{device}_<YYYYmmddTHHMMSS>.<ending>), found none")
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
