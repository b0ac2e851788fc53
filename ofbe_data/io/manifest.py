"""The session manifest (``session.yaml``): typed records, validation and writing.

The contract is shared/spec/raw-formats.md; docs/formats.md explains it. Validation is
strict about what the pipeline relies on (kinds, roles, formats, device references, paths
that stay inside the session folder, unique ids) and about keys: an unknown key (``temprature_unit``,
or ``fit_model``, a labelling parameter) is an error with the closest known key or where it belongs.
The known keys are the records' fields (:data:`TOP_KEYS`, :func:`device_keys`…), so a field added
to a record is known at once.
"""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import ManifestError
from ofbe_data.io.device_options import (
    ACC_UNITS,
    COLUMN_KEYS,
    GYRO_KEYS,
    GYRO_UNITS,
    KINDS,
    TEMPERATURE_UNITS,
    TIME_UNITS,
    WHITESPACE,
    BinOptions,
    CsvMapping,
    DeviceSpec,
    option_key_paths,
    option_keys,
)
from ofbe_data.io.formats import formats
from ofbe_data.io.gravity import local_gravity
from ofbe_data.io.shared_files import distinct_columns, file_identity, same_file_note
from ofbe_data.io.typedconfig import closest_key, key_homes, record_keys, register_document, unknown_key_found
from ofbe_data.io.yamlio import FieldPath, YamlDocument, YamlProblem, format_field, read_yaml

MANIFEST_FORMAT = "ofbe-session/1"
MANIFEST_NAME = "session.yaml"
ROLES = ("dut", "reference")
ID_PATTERN = re.compile(r"^[A-Za-z0-9._-]+$")
"""Campaign, session, device and recording ids."""


@dataclass(frozen=True)
class Site:
    """Where a session was recorded; gives the local gravity magnitude.

    Either ``gravity_mps2`` (an override, m/s²) or ``latitude_deg`` and ``height_m``.
    """

    latitude_deg: float | None = None
    height_m: float | None = None
    gravity_mps2: float | None = None

    @property
    def g_local(self) -> float:
        """Local gravity magnitude, m/s² (override, else WGS-84 + free-air)."""
        if self.gravity_mps2 is not None:
            return self.gravity_mps2
        assert self.latitude_deg is not None
        return local_gravity(self.latitude_deg, self.height_m or 0.0)

    def to_dict(self) -> dict[str, float]:
        if self.gravity_mps2 is not None:
            return {"gravity_mps2": self.gravity_mps2}
        return {"latitude_deg": float(self.latitude_deg or 0.0), "height_m": float(self.height_m or 0.0)}


@dataclass(frozen=True)
class RecordingSpec:
    """One recording of a session: its id, nominal tripod setting and files per device."""

    id: str
    files: dict[str, str]
    nominal: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id}
        if self.nominal:
            out["nominal"] = dict(self.nominal)
        out["files"] = dict(self.files)
        return out


@dataclass(frozen=True)
class SessionManifest:
    """A validated ``session.yaml``.

    Attributes
    ----------
    folder
        The session folder (file paths are relative to it).
    campaign, session, kind
        Identity and kind of the session.
    site
        Site, giving ``g_local``.
    power_cycle
        Bias-instance id of this power-on period.
    devices
        Device specs by id, in file order.
    recordings
        Recordings in file order.
    """

    folder: Path
    campaign: str
    session: str
    kind: str
    site: Site
    power_cycle: int
    devices: dict[str, DeviceSpec]
    recordings: tuple[RecordingSpec, ...]

    @property
    def path(self) -> Path:
        """The manifest file."""
        return self.folder / MANIFEST_NAME

    @property
    def g_local(self) -> float:
        """Local gravity magnitude, m/s²."""
        return self.site.g_local

    @property
    def duts(self) -> list[DeviceSpec]:
        """Devices under test, in file order."""
        return [d for d in self.devices.values() if d.role == "dut"]

    @property
    def reference(self) -> DeviceSpec | None:
        """The reference device, or None."""
        refs = [d for d in self.devices.values() if d.role == "reference"]
        return refs[0] if refs else None

    def file_path(self, recording: RecordingSpec, device: str) -> Path:
        """Absolute-ish path of one device's file in one recording."""
        return self.folder / recording.files[device]

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "format": MANIFEST_FORMAT,
            "campaign": self.campaign,
            "session": self.session,
            "kind": self.kind,
            "site": self.site.to_dict(),
            "power_cycle": self.power_cycle,
            "devices": {k: d.to_dict() for k, d in self.devices.items()},
            "recordings": [r.to_dict() for r in self.recordings],
        }
        return out


TOP_KEYS = (record_keys(SessionManifest) - {"folder"}) | {"format", "gravity_mps2"}
"""Top-level keys: :class:`SessionManifest`'s fields but ``folder``, ``format`` and the g override."""
SITE_KEYS = record_keys(Site)
DEVICE_KEYS = record_keys(DeviceSpec) - {"id", "csv", "bin"}
"""Keys of every device entry: :class:`DeviceSpec`'s fields but ``id`` (its key under ``devices``)
and the options records, whose fields stand beside these (:func:`device_keys`)."""
RECORDING_KEYS = record_keys(RecordingSpec)


def format_choices() -> tuple[str, ...]:
    """The values of a device's ``format``: the registered device formats, in the registry's order
    (:func:`ofbe_data.io.formats.formats`; a format module registered later is one at once)."""
    return tuple(f.name for f in formats())


def device_keys(fmt: Any) -> frozenset[str]:
    """Keys of a device entry of format ``fmt`` (of any format when ``fmt`` is not a format)."""
    return DEVICE_KEYS | option_keys(fmt if fmt in format_choices() else None)


@functools.cache
def manifest_key_paths() -> dict[str, tuple[str, ...]]:
    """Every key a manifest may hold, with its paths: ``site.latitude_deg``,
    ``recordings[i].nominal``, ``devices.<id>.time_unit with format: csv``."""
    out: dict[str, tuple[str, ...]] = {}
    for prefix, keys in (("", TOP_KEYS), ("site.", SITE_KEYS), ("devices.<id>.", DEVICE_KEYS),
                         ("recordings[i].", RECORDING_KEYS)):
        out.update({k: out.get(k, ()) + (prefix + k,) for k in sorted(keys)})
    for key, paths in option_key_paths("devices.<id>.").items():
        out[key] = out.get(key, ()) + paths
    return out


register_document(MANIFEST_NAME, manifest_key_paths)


class _Validator:
    """Walks the plain data of a manifest and raises :class:`ManifestError` with lines."""

    def __init__(self, path: Path, doc: YamlDocument) -> None:
        self.path = path
        self.doc = doc

    def fail(self, where: FieldPath, expected: str, found: str) -> ManifestError:
        return ManifestError(self.path, format_field(where), expected, found, self.doc.line_of(where))

    def get(self, mapping: dict[str, Any], where: FieldPath, key: str) -> Any:
        """``mapping[key]``, or a ManifestError saying the key is missing."""
        if key not in mapping:
            return self._missing(where, key)
        return mapping[key]

    def _missing(self, where: FieldPath, key: str) -> Any:
        raise ManifestError(
            self.path, format_field([*where, key]), "this key", "it missing", self.doc.line_of(where)
        )

    def known_keys(self, mapping: dict[Any, Any], where: FieldPath, known: frozenset[str]) -> None:
        """Refuse the first key of ``mapping`` (in file order) not in ``known``: a ManifestError at
        it, with where the key belongs or the closest known key (:func:`unknown_key_found`)."""
        unknown = [str(k) for k in mapping if k not in known]
        if unknown:
            name = unknown[0]
            raise self.fail([*where, name], "one of " + ", ".join(sorted(known)), unknown_key_found(
                name, known, manifest_key_paths().get(name, ()), lambda: key_homes(name, manifest=False)))

    def mapping(self, value: Any, where: FieldPath) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, "a mapping", _describe(value))
        return value

    def ident(self, value: Any, where: FieldPath) -> str:
        if not isinstance(value, str) or not ID_PATTERN.match(value):
            raise self.fail(where, "an id of [A-Za-z0-9._-]+", _describe(value))
        return value

    def choice(self, value: Any, where: FieldPath, choices: tuple[str, ...]) -> str:
        if value not in choices:
            raise self.fail(where, "one of " + ", ".join(choices), _describe(value))
        return str(value)

    def number(self, value: Any, where: FieldPath, lo: float, hi: float) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
            raise self.fail(where, f"a number in [{lo:g}, {hi:g}]", _describe(value))
        return float(value)

    def integer(self, value: Any, where: FieldPath, lo: int = 0) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < lo:
            raise self.fail(where, f"an integer >= {lo}", _describe(value))
        return int(value)


def _describe(value: Any) -> str:
    if value is None:
        return "nothing (null)"
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def _parse_site(v: _Validator, data: dict[str, Any]) -> Site:
    top_g = data.get("gravity_mps2")
    site_raw = data.get("site")
    if site_raw is None and top_g is None:
        v._missing([], "site")
    site = v.mapping(site_raw, ["site"]) if site_raw is not None else {}
    v.known_keys(site, ["site"], SITE_KEYS)
    g = site.get("gravity_mps2", top_g)
    where: FieldPath = ["site", "gravity_mps2"] if "gravity_mps2" in site else ["gravity_mps2"]
    if g is not None:
        return Site(gravity_mps2=v.number(g, where, 9.7, 9.9))
    lat = v.number(v.get(site, ["site"], "latitude_deg"), ["site", "latitude_deg"], -90.0, 90.0)
    h_raw = site.get("height_m", 0.0)
    h = v.number(h_raw, ["site", "height_m"], -500.0, 9000.0)
    return Site(latitude_deg=lat, height_m=h)


def _parse_rotation(v: _Validator, value: Any, where: FieldPath) -> np.ndarray:
    try:
        m = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise v.fail(where, "a 3x3 matrix of numbers", _describe(value)) from None
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise v.fail(where, "a 3x3 matrix of numbers", _describe(value))
    if not np.allclose(m @ m.T, np.eye(3), atol=2e-3) or np.linalg.det(m) < 0:
        raise v.fail(where, "a rotation (orthonormal rows, determinant +1)",
                     f"determinant {np.linalg.det(m):.4f} and M·Mᵀ off identity by "
                     f"{np.abs(m @ m.T - np.eye(3)).max():.2g}")
    return m


def _per_axis(v: _Validator, value: Any, where: FieldPath, lo: float, hi: float
              ) -> tuple[float, float, float] | float:
    if isinstance(value, list):
        if len(value) != 3:
            raise v.fail(where, f"a number in [{lo:g}, {hi:g}] or three of them [x, y, z]", _describe(value))
        x, y, z = (v.number(item, [*where, i], lo, hi) for i, item in enumerate(value))
        return (x, y, z)
    return v.number(value, where, lo, hi)


def _parse_csv_mapping(v: _Validator, entry: dict[str, Any], where: list[str | int]) -> CsvMapping:
    header = entry.get("header", True)
    if not isinstance(header, bool):
        raise v.fail([*where, "header"], "true or false", _describe(header))
    cols = v.mapping(v.get(entry, where, "columns"), [*where, "columns"])
    for key in cols:
        if key not in COLUMN_KEYS:
            match = closest_key(str(key), COLUMN_KEYS)
            raise v.fail([*where, "columns", key], "a column key among " + ", ".join(COLUMN_KEYS),
                         _describe(key) + (f" (did you mean {match}?)" if match is not None else ""))
    columns: dict[str, str | int] = {}
    for key in COLUMN_KEYS:
        if key not in cols:
            if key in ("t", "temperature", *GYRO_KEYS):
                continue
            v.get(cols, [*where, "columns"], key)
        name = cols[key]
        if header:
            if isinstance(name, bool) or not isinstance(name, str | int) or name == "":
                raise v.fail([*where, "columns", key], "a column name", _describe(name))
            name = str(name)
        elif isinstance(name, bool) or not isinstance(name, int) or name < 0:
            raise v.fail([*where, "columns", key], "a 0-based column index (header: false)", _describe(name))
        columns[key] = name
    given = [k for k in GYRO_KEYS if k in columns]
    if given and len(given) != len(GYRO_KEYS):
        raise v.fail([*where, "columns"], "all three angular-rate columns gx, gy, gz or none of them",
                     "only " + ", ".join(given))
    if len(set(columns.values())) != len(columns):
        raise v.fail([*where, "columns"], "a different column for each key", _describe(cols))
    time_unit = v.choice(entry.get("time_unit", "s"), [*where, "time_unit"], TIME_UNITS)
    rate = None
    if entry.get("sample_rate_hz") is not None:
        rate = v.number(entry["sample_rate_hz"], [*where, "sample_rate_hz"], 1e-3, 1e7)
    if rate is None and ("t" not in columns or time_unit == "samples"):
        what = "time_unit: samples" if "t" in columns else "no t column"
        raise v.fail([*where, "sample_rate_hz"], f"the sample rate in Hz ({what})", "it missing")
    acc_unit = v.choice(entry.get("acc_unit", "m/s2"), [*where, "acc_unit"], ACC_UNITS)
    lsb: tuple[float, float, float] | float | None = None
    zero: tuple[float, float, float] | float = 0.0
    if acc_unit == "counts":
        lsb = _per_axis(v, v.get(entry, where, "lsb_per_g"), [*where, "lsb_per_g"], 1e-9, 1e12)
        zero = _per_axis(v, entry.get("zero_counts", 0), [*where, "zero_counts"], -1e12, 1e12)
    else:
        for key in ("lsb_per_g", "zero_counts"):
            if key in entry:
                raise v.fail([*where, key], f"no {key} unless acc_unit is counts", f"acc_unit {acc_unit}")
    skip = v.integer(entry.get("skip_rows", 0), [*where, "skip_rows"])
    delim = entry.get("delimiter", ",")
    if delim != WHITESPACE and (not isinstance(delim, str) or len(delim) != 1 or delim in "\r\n\""):
        raise v.fail([*where, "delimiter"], "a single delimiter character or whitespace", _describe(delim))
    comment = entry.get("comment")
    if comment is not None and (not isinstance(comment, str) or not comment or "\n" in comment):
        raise v.fail([*where, "comment"], "the string that starts a comment line", _describe(comment))
    t_unit = v.choice(entry.get("temperature_unit", "C"), [*where, "temperature_unit"], TEMPERATURE_UNITS)
    range_g = None
    if entry.get("range_g") is not None:
        range_g = v.number(entry["range_g"], [*where, "range_g"], 1e-3, 1e4)
    gyro_unit = v.choice(entry.get("gyro_unit", "rad/s"), [*where, "gyro_unit"], GYRO_UNITS)
    sort_by_time = entry.get("sort_by_time", False)
    if not isinstance(sort_by_time, bool):
        raise v.fail([*where, "sort_by_time"], "true or false", _describe(sort_by_time))
    if sort_by_time and ("t" not in columns or time_unit == "samples"):
        raise v.fail([*where, "sort_by_time"], "a t column of time stamps to sort by",
                     "no t column" if "t" not in columns else "time_unit: samples")
    return CsvMapping(columns, time_unit, acc_unit, lsb, skip, str(delim), header, comment, rate, zero,
                      t_unit, range_g, gyro_unit, sort_by_time)


def _parse_bin_options(v: _Validator, entry: dict[str, Any], where: list[str | int]) -> BinOptions:
    rate = None
    if entry.get("sample_rate_hz") is not None:
        rate = v.number(entry["sample_rate_hz"], [*where, "sample_rate_hz"], 1e-3, 1e7)
    unit = v.choice(entry.get("acc_unit", "g"), [*where, "acc_unit"], ("g", "mg", "m/s2"))
    return BinOptions(rate, unit)


def _parse_devices(v: _Validator, data: dict[str, Any]) -> dict[str, DeviceSpec]:
    raw = v.mapping(v.get(data, [], "devices"), ["devices"])
    if not raw:
        raise v.fail(["devices"], "at least one device", "none")
    devices: dict[str, DeviceSpec] = {}
    for dev_id, entry in raw.items():
        where: list[str | int] = ["devices", str(dev_id)]
        v.ident(dev_id, where)
        entry = v.mapping(entry, where)
        v.known_keys(entry, where, device_keys(entry.get("format")))
        model = v.get(entry, where, "model")
        if not isinstance(model, str) or not model:
            raise v.fail([*where, "model"], "a model name", _describe(model))
        role = v.choice(v.get(entry, where, "role"), [*where, "role"], ROLES)
        fmt = v.choice(v.get(entry, where, "format"), [*where, "format"], format_choices())
        r2s = None
        if entry.get("reference_to_sensor") is not None:
            r2s = _parse_rotation(v, entry["reference_to_sensor"], [*where, "reference_to_sensor"])
        csv = _parse_csv_mapping(v, entry, where) if fmt == "csv" else None
        opts = _parse_bin_options(v, entry, where) if fmt == "mscip-bin" else None
        devices[str(dev_id)] = DeviceSpec(str(dev_id), model, role, fmt, r2s, csv, opts)
    return devices


def _check_kind_rules(v: _Validator, kind: str, devices: dict[str, DeviceSpec]) -> None:
    refs = [d.id for d in devices.values() if d.role == "reference"]
    duts = [d.id for d in devices.values() if d.role == "dut"]
    if not duts:
        raise v.fail(["devices"], "at least one device with role dut", "none")
    if kind == "rotated" and len(refs) != 1:
        raise v.fail(["devices"], "exactly one device with role reference for kind rotated",
                     f"{len(refs)} ({', '.join(refs) or 'none'})")
    if kind != "rotated" and refs:
        raise v.fail(["devices", refs[0], "role"], f"no reference device for kind {kind}",
                     "role reference")


def _check_path(v: _Validator, folder: Path, rel: Any, where: FieldPath) -> str:
    if not isinstance(rel, str) or not rel:
        raise v.fail(where, "a file path relative to the session folder", _describe(rel))
    if os.path.isabs(rel) or re.match(r"^[A-Za-z]:", rel):
        raise v.fail(where, "a path relative to the session folder", f"absolute path {rel!r}")
    norm = os.path.normpath(rel)
    if norm == ".." or norm.startswith(".." + os.sep) or norm.startswith("../"):
        raise v.fail(where, "a path that stays inside the session folder", f"{rel!r}, which escapes it")
    real_folder = os.path.realpath(folder)
    real = os.path.realpath(os.path.join(folder, rel))
    if os.path.commonpath([real_folder, real]) != real_folder:
        raise v.fail(where, "a path that stays inside the session folder",
                     f"{rel!r}, which resolves (through a link) to {real}")
    return rel


def _parse_recordings(v: _Validator, data: dict[str, Any], devices: dict[str, DeviceSpec],
                      folder: Path) -> tuple[RecordingSpec, ...]:
    raw = v.get(data, [], "recordings")
    if not isinstance(raw, list) or not raw:
        raise v.fail(["recordings"], "a non-empty list of recordings", _describe(raw))
    seen_ids: dict[str, int] = {}
    seen_paths: dict[str, tuple[str, str]] = {}
    out: list[RecordingSpec] = []
    for i, entry in enumerate(raw):
        where: list[str | int] = ["recordings", i]
        entry = v.mapping(entry, where)
        v.known_keys(entry, where, RECORDING_KEYS)
        rid = v.ident(v.get(entry, where, "id"), [*where, "id"])
        if rid in seen_ids:
            raise v.fail([*where, "id"], "unique recording ids",
                         f"duplicate id {rid!r} (also recordings[{seen_ids[rid]}].id)")
        seen_ids[rid] = i
        nominal_raw = entry.get("nominal") or {}
        nominal_raw = v.mapping(nominal_raw, [*where, "nominal"])
        nominal: dict[str, float] = {}
        for key, val in nominal_raw.items():
            nominal[str(key)] = v.number(val, [*where, "nominal", str(key)], -1e6, 1e6)
        files = v.mapping(v.get(entry, where, "files"), [*where, "files"])
        for dev in files:
            if dev not in devices:
                raise v.fail([*where, "files", str(dev)], "a device declared under devices ("
                             + ", ".join(devices) + ")", f"unknown device {dev!r}")
        for dev in devices:
            if dev not in files:
                raise v.fail([*where, "files"], f"a file for declared device {dev!r}",
                             "no entry for it")
        clean: dict[str, str] = {}
        here: dict[str, tuple[str, str]] = {}
        for dev, rel in files.items():
            fw: list[str | int] = [*where, "files", str(dev)]
            rel = _check_path(v, folder, rel, fw)
            key = file_identity(folder / rel, rel)
            if key in here:  # two triads of one file: each device reads its own columns
                other, named = here[key]
                if not distinct_columns(devices[other].csv, devices[str(dev)].csv):
                    raise v.fail(fw, "a file shared by devices of one recording only when each reads its "
                                 "own columns (format csv, different ax, ay, az)",
                                 f"{rel!r}, also named for device {other!r}" + same_file_note(rel, named))
            elif key in seen_paths:
                at, named = seen_paths[key]
                raise v.fail(fw, "a file used in one recording only",
                             f"{rel!r}, also named at {at}" + same_file_note(rel, named))
            seen_paths[key] = (format_field(fw), rel)
            here.setdefault(key, (str(dev), rel))
            clean[str(dev)] = rel
        out.append(RecordingSpec(rid, clean, nominal))
    return tuple(out)


def parse_manifest(path: Path, doc: YamlDocument) -> SessionManifest:
    """Validate a parsed manifest document; see :func:`load_manifest`."""
    v = _Validator(path, doc)
    data = v.mapping(doc.data, [])
    fmt = v.get(data, [], "format")
    if fmt != MANIFEST_FORMAT:
        raise v.fail(["format"], MANIFEST_FORMAT, _describe(fmt))
    v.known_keys(data, [], TOP_KEYS)
    campaign = v.ident(v.get(data, [], "campaign"), ["campaign"])
    session = v.ident(v.get(data, [], "session"), ["session"])
    kind = v.choice(v.get(data, [], "kind"), ["kind"], KINDS)
    site = _parse_site(v, data)
    power_cycle = v.integer(v.get(data, [], "power_cycle"), ["power_cycle"])
    devices = _parse_devices(v, data)
    _check_kind_rules(v, kind, devices)
    recordings = _parse_recordings(v, data, devices, path.parent)
    return SessionManifest(path.parent, campaign, session, kind, site, power_cycle, devices, recordings)


def load_manifest(path_or_folder: str | Path) -> SessionManifest:
    """Read and validate a session manifest.

    Parameters
    ----------
    path_or_folder
        The ``session.yaml`` file or the session folder holding it.

    Returns
    -------
    SessionManifest

    Raises
    ------
    ManifestError
        Naming the file, the line and the field, with what was expected and found (an unknown
        key at any level: with the closest known key or where it belongs).
    """
    path = Path(path_or_folder)
    if path.is_dir():
        path = path / MANIFEST_NAME
    if not path.is_file():
        raise ManifestError(path, "<file>", "a session manifest file", "no such file")
    try:
        doc = read_yaml(path)
    except YamlProblem as exc:
        raise ManifestError(path, exc.field, exc.expected, exc.found, exc.line) from None
    return parse_manifest(path, doc)


def write_manifest(manifest: SessionManifest, path: str | Path | None = None) -> Path:
    """Write a manifest as YAML (atomically).

    Parameters
    ----------
    manifest
        The manifest to write.
    path
        Target file; defaults to ``manifest.path``.

    Returns
    -------
    Path
        The written file.
    """
    target = Path(path) if path is not None else manifest.path
    text = yaml.safe_dump(manifest.to_dict(), sort_keys=False, default_flow_style=None, width=100)
    write_bytes_atomic(target, text.encode("utf-8"))
    return target
