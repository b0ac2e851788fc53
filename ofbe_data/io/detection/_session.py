"""What the files of a session folder are, together: which are data files (:func:`data_files`),
the device each belongs to (:func:`assign_devices`), the recordings they pair up into
(:func:`group_recordings`), one manifest device per accelerometer triad of its files
(:func:`init_devices`, from each file's :class:`~ofbe_data.io.detection.Detection`), and the
power cycle an explicit pattern of the session's name states (:func:`power_cycle_of`), each with
its evidence. A case the files do not settle raises :class:`SessionFilesError` naming what to
give. ``ofbe-session init`` (:mod:`ofbe_data.cli.session`) parses the flags, prints and writes.
"""

from __future__ import annotations

import fnmatch
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ofbe_data.core.errors import OfbeError
from ofbe_data.io.detection._result import Detection, show_value
from ofbe_data.io.manifest import MANIFEST_NAME


class SessionFilesError(OfbeError):
    """A session folder's files that do not settle its devices or recordings; the message names
    the file or flag and what to give (``--device ID=GLOB``, separate devices or folders)."""


DATA_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".log", ".ssv", ".asc", ".bin", ".raw", ".mscip")
"""Files ``init`` takes for data files (others are listed as ignored)."""


def sanitise(name: str) -> str:
    """An id of ``[A-Za-z0-9._-]+`` from a folder or file name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", name).strip("-") or "x"


def data_files(folder: Path) -> tuple[list[str], list[str]]:
    """(data files, ignored files) under ``folder``, relative POSIX paths, sorted."""
    found, ignored = [], []
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if not p.is_file() or any(part.startswith((".", "_")) for part in Path(rel).parts):
            continue
        if p.name == MANIFEST_NAME:
            continue
        (found if p.suffix.lower() in DATA_SUFFIXES else ignored).append(rel)
    return found, ignored


def assign_devices(files: list[str], patterns: list[tuple[str, str]]) -> dict[str, list[str]]:
    """Files per device id (first matching ``--device`` pattern; all to ``dut`` without any)."""
    if not patterns:
        return {"dut": list(files)}
    out: dict[str, list[str]] = {dev: [] for dev, _ in patterns}
    for rel in files:
        dev = next((d for d, g in patterns if fnmatch.fnmatch(rel, g) or fnmatch.fnmatch(Path(rel).name, g)),
                   None)
        if dev is None:
            globs = ", ".join(g for _, g in patterns)
            raise SessionFilesError(f"{rel}: matches no --device pattern ({globs}): give --device ID=GLOB "
                                    "for it")
        out[dev].append(rel)
    for dev, got in out.items():
        if not got:
            raise SessionFilesError(f"--device {dev}: its pattern matches no data file")
    return out


def _pair_up(by_device: dict[str, list[str]], key: Any) -> dict[str, dict[str, str]] | None:
    """Files grouped by ``key(file)`` when every group holds one file of every device, else None."""
    groups: dict[str, dict[str, str]] = {}
    for dev, files in by_device.items():
        for f in files:
            group = groups.setdefault(key(f), {})
            if dev in group:
                return None
            group[dev] = f
    return groups if all(len(g) == len(by_device) for g in groups.values()) else None


def group_recordings(by_device: dict[str, list[str]]) -> list[tuple[str, dict[str, str]]]:
    """Recordings as (id, files per device).

    One device: one recording per file (id: its folder when each file has its own, else its
    name). Several: the files of one recording share a folder (``rec-01/dut.csv``,
    ``rec-01/ref.csv``), else a name (``dut/rec-01.csv``, ``ref/rec-01.csv``), else they pair
    up in sorted order (ids ``rec-01``…).

    Raises
    ------
    SessionFilesError
        Several devices whose files pair up in none of these ways.
    """
    devices = list(by_device)
    if len(devices) == 1:
        files = by_device[devices[0]]
        parents = [str(Path(f).parent) for f in files]
        by_parent = "." not in parents and len(set(parents)) == len(parents)
        ids = [sanitise(p.replace("/", "-")) if by_parent else sanitise(Path(f).stem) for f, p in
               zip(files, parents, strict=True)]
        if len(set(ids)) != len(ids):
            ids = [sanitise(str(Path(f).with_suffix("")).replace("/", "-")) for f in files]
        return [(rid, {devices[0]: f}) for rid, f in zip(ids, files, strict=True)]
    keys = [lambda f: str(Path(f).parent), lambda f: Path(f).stem]
    if any(Path(f).parent == Path(".") for fs in by_device.values() for f in fs):
        keys = keys[1:]
    for key in keys:
        groups = _pair_up(by_device, key)
        if groups is not None:
            return [(sanitise(k.replace("/", "-")), groups[k]) for k in sorted(groups)]
    counts = {d: len(fs) for d, fs in by_device.items()}
    if len(set(counts.values())) != 1:
        raise SessionFilesError("the devices' files pair up neither by folder, nor by name, nor in order "
                                f"({', '.join(f'{d}: {n} files' for d, n in counts.items())}): put each "
                                "recording in its own folder holding one file per device (or check the "
                                "--device patterns)")
    n = next(iter(counts.values()))
    return [(f"rec-{k + 1:02d}", {d: by_device[d][k] for d in devices}) for k in range(n)]


@dataclass
class DeviceEntry:
    """One device of the manifest ``init`` writes, with the evidence of each key.

    Attributes
    ----------
    id
        Device id (``dut``, a ``--device`` id, or ``<id>-<triad>`` for one triad of a file with several).
    role
        ``dut`` or ``reference``.
    format
        The detected format.
    model
        Model name (``--model``, the file's header, or ``unknown``).
    entry
        The manifest keys of its format's options (the csv mapping, the mscip-bin options).
    evidence
        Manifest key → why it has its value (written as a YAML comment beside the key).
    notes
        Remarks written as comment lines above the entry.
    """

    id: str
    role: str
    format: str
    model: str
    entry: dict[str, Any]
    evidence: dict[str, str]
    notes: list[str]


def _entry(det: Detection, part: str) -> dict[str, Any]:
    """The manifest keys of one part of a detection (its options for a format without parts)."""
    if det.format != "csv":
        return dict(det.options)
    return next(p.mapping.to_dict() for p in det.parts if p.label == part)


def _labels(det: Detection) -> list[str]:
    return [p.label for p in det.parts] if det.format == "csv" else [""]


def _device(dev: str, dets: list[Detection], models: dict[str, str], part: str = "", base: str = ""
            ) -> DeviceEntry:
    """The manifest entry of device ``dev`` from the detections of its files (of ``part``, the
    accelerometer triad it reads, when its files hold several)."""
    first = dets[0]
    for d in dets[1:]:
        if d.format != first.format:
            raise SessionFilesError(f"{d.path}: format {d.format}, but {first.path.name} of the same device "
                                    f"{dev} is {first.format}: give each kind of file its own --device")
        a, b = _entry(first, part), _entry(d, part)
        if a != b:
            key = next(k for k in list(a) + list(b) if a.get(k) != b.get(k))
            raise SessionFilesError(f"{d.path}: {key} {show_value(b.get(key))}, but {first.path.name} of the "
                                    f"same device {dev} has {show_value(a.get(key))}: one device's files "
                                    "must share a layout (map them to separate devices or sessions)")
    model = models.get(dev) or models.get(base) or first.model or "unknown"
    given = dev in models or base in models
    evidence = {"model": "given with --model" if given else (first.evidence("model") or
                "not in the file: give --model ID=MODEL")}
    entry = _entry(first, part)
    same = f" (in {first.path.name}; the {len(dets)} files agree)" if len(dets) > 1 else ""
    label = part or None
    for d in first.decisions:
        if d.part in (None, label):
            evidence.setdefault(d.key, (first.evidence(d.key, label) or d.evidence) + same)
    notes = [f"{d.key}: {show_value(d.value)} ({d.evidence})" for d in first.decisions
             if d.key in ("trailing_delimiter", "zero", "decimal_comma", "unit_row", "gyro")
             and d.part in (None, label)]
    return DeviceEntry(dev, "dut", first.format, model, entry, evidence, notes)


def init_devices(by_device: dict[str, list[str]], dets: dict[str, Detection], models: dict[str, str]
             ) -> tuple[list[DeviceEntry], dict[str, list[str]]]:
    """The manifest's devices, and the device ids each ``--device`` (or ``dut``) became: one per
    accelerometer triad of its files (``dut-1``, ``dut-2`` for a file with two)."""
    devices: list[DeviceEntry] = []
    ids: dict[str, list[str]] = {}
    for dev, files in by_device.items():
        group = [dets[f] for f in files]
        labels = _labels(group[0])
        for d in group[1:]:
            if _labels(d) != labels:
                raise SessionFilesError(f"{d.path}: accelerometer triads {_labels(d)}, but "
                                        f"{group[0].path.name} of the same device {dev} has {labels}: map "
                                        "them to separate devices")
        if len(labels) == 1:
            devices.append(_device(dev, group, models))
            ids[dev] = [dev]
            continue
        ids[dev] = [f"{dev}-{label}" for label in labels]
        for label, sub in zip(labels, ids[dev], strict=True):
            d = _device(sub, group, models, label, dev)
            others = ", ".join(x for x in ids[dev] if x != sub)
            d.notes.append(f"one of {len(labels)} accelerometer triads in each file: reads the same file as "
                           f"{others}, its own ax, ay, az")
            devices.append(d)
    return devices, ids


_POWER_CYCLE = re.compile(r"(?:^|[^a-z0-9])(?P<word>power[_-]?cycle|pwr[_-]?cycle|cycle|pc)[_-]?(?P<n>\d+)",
                          re.IGNORECASE)


def power_cycle_of(session: str) -> tuple[int | None, str]:
    """The power-cycle number an explicit pattern of a session id states (``pc3``, ``pc-003``,
    ``power_cycle_3``, ``cycle3``), and its evidence; None when there is none (other digits, as in
    ``imu9`` or ``mpu9255``, are usually a model number and are never taken)."""
    m = _POWER_CYCLE.search(session)
    if m:
        text = m.group(0).lstrip("-_.")
        return int(m.group("n")), f"{text!r} in the session id {session!r}"
    return None, (f"no power-cycle pattern (pc3, pc-003, power_cycle_3, cycle3) in the session id "
                  f"{session!r}; its digits are not taken (often a model number): 1 — give --power-cycle N, "
                  "unique per device within the campaign")
