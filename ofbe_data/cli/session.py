"""``ofbe-session``: write a session's manifest from its files (``init``), and check a session
before labelling it (``check``).

``init DIR`` detects each file's format, columns, units and rate (:mod:`ofbe_data.io.detect`),
prints every decision with its evidence, and writes ``DIR/session.yaml`` with the evidence as
YAML comments beside the keys. A case the files do not settle stops with the flag to give.

``check DIR...`` validates each session, reads every file and runs labelling in memory (nothing
is written, the raw folder is never touched), and prints per file what was found and what
labelling would reject and why.

Exit status: 0 (``init``: manifest written; ``check``: every file reads and every recording of
every device under test would be labelled), 1 (a file cannot be read, or ``check`` finds
something labelling would reject), 2 (usage: a flag is needed or wrong, or ``session.yaml``
exists without ``--force``).
"""

from __future__ import annotations

import argparse
import fnmatch
import math
import re
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, add_params, command, fail
from ofbe_data.core.errors import OfbeError, OutputExistsError
from ofbe_data.io.detect import Detection, Hints, show_value, sniff_text
from ofbe_data.io.detect_units import DetectionError, fmt_num, quiet_mean
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import (
    ACC_UNITS,
    ID_PATTERN,
    KINDS,
    MANIFEST_FORMAT,
    MANIFEST_NAME,
    TIME_UNITS,
    SessionManifest,
    load_manifest,
    parse_manifest,
)
from ofbe_data.io.recording import Recording
from ofbe_data.io.yamlio import YamlDocument
from ofbe_data.labelling.batch import UsageError, expand_sessions
from ofbe_data.labelling.checks import MAX_LEVEL_TILT_DEG
from ofbe_data.labelling.labels import SessionLabels, label_params_from, label_session, read_label_section
from ofbe_data.labelling.next_pose import report_lines

PROG = "ofbe-session"
DATA_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".log", ".ssv", ".asc", ".bin", ".raw", ".mscip")
"""Files ``init`` takes for data files (others are listed as ignored)."""
REFERENCE_FORMATS = ("mscip-csv", "mscip-bin")
"""Formats of the reference IMU: a device of these is the reference of a rotated session."""


# --------------------------------------------------------------------------- arguments


def _per_axis(text: str) -> float | tuple[float, float, float]:
    parts = [float(p) for p in text.split(",")]
    if len(parts) == 1:
        return parts[0]
    if len(parts) == 3:
        return (parts[0], parts[1], parts[2])
    raise argparse.ArgumentTypeError(f"expected N or X,Y,Z, found {text!r}")


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0 or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a number > 0, found {text!r}")
    return value


def _pair(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"expected ID=VALUE, found {text!r}")
    return key.strip(), value.strip()


def _columns(text: str) -> dict[str, str]:
    out = dict(_pair(p) for p in text.split(","))
    bad = [k for k in out if k not in ("t", "ax", "ay", "az", "temperature")]
    if bad or not {"ax", "ay", "az"} <= set(out):
        raise argparse.ArgumentTypeError(f"expected t=…,ax=…,ay=…,az=…[,temperature=…], found {text!r}")
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description="Write a session's manifest from its data files "
                                "(init), or check a session before labelling it (check).")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="{init,check}")
    i = sub.add_parser("init", help="write DIR/session.yaml for the data files in DIR",
                       description="Detect each data file's format, columns, units and rate, print every "
                       "decision with its evidence and write DIR/session.yaml (evidence as comments). Each "
                       "file is one recording. A case the files do not settle stops and names the flag "
                       "to give.")
    i.add_argument("dir", help="session folder holding the data files (its parent's name is the campaign)")
    i.add_argument("--kind", choices=KINDS, help="session kind (default: rotated when a device is a "
                   "reference, else gravity-aligned)")
    i.add_argument("--device", action="append", type=_pair, default=[], metavar="ID=GLOB",
                   help="files matching GLOB (relative path or file name) belong to device ID; repeat "
                   "per device (default: every file to one device 'dut')")
    i.add_argument("--reference", metavar="ID", help="the reference device of a rotated session (default: "
                   "the device whose files are mscip-csv or mscip-bin)")
    i.add_argument("--model", action="append", type=_pair, default=[], metavar="ID=MODEL",
                   help="device model (default: from the file header, else 'unknown')")
    i.add_argument("--rate", type=_positive, metavar="HZ", help="sample rate: needed for files without a "
                   "time column or with a sample index; otherwise the nominal rate")
    i.add_argument("--unit", choices=ACC_UNITS, help="acceleration unit of the csv files")
    i.add_argument("--lsb-per-g", type=_per_axis, metavar="N|X,Y,Z", help="counts per g (--unit counts)")
    i.add_argument("--zero-counts", type=_per_axis, metavar="Z|X,Y,Z", help="counts at zero specific "
                   "force (--unit counts; e.g. 32768 for an unsigned 16-bit converter)")
    i.add_argument("--time-unit", choices=TIME_UNITS, help="unit of the time column")
    i.add_argument("--time-column", metavar="NAME", help="the time column (a 0-based index when the file "
                   "has no column line)")
    i.add_argument("--columns", type=_columns, metavar="t=NAME,ax=NAME,ay=NAME,az=NAME",
                   help="every column by name (0-based indices without a column line); t may be left out "
                   "with --rate")
    site = i.add_mutually_exclusive_group()
    site.add_argument("--site", metavar="LAT,HEIGHT_M", help="latitude (degrees) and height (m) of the "
                      "site: local gravity from WGS-84")
    site.add_argument("--gravity", type=float, metavar="G", help="local gravity, m/s²")
    i.add_argument("--power-cycle", type=int, metavar="N", help="bias-instance id (default: the number "
                   "the session folder's name ends with, else 0)")
    i.add_argument("--force", action="store_true", help="replace an existing session.yaml")
    c = sub.add_parser("check", help="validate sessions and say what labelling would do",
                       description="Validate each session, read every file and run labelling in memory "
                       "(nothing is written); print per file the format, rows, rate, duration, units, "
                       "‖mean‖ against g_local, the stationary segment or poses, and what labelling would "
                       "reject and why. Exit 0 when every recording would be labelled.")
    c.add_argument("dirs", nargs="+", help="session folders (or campaign folders of sessions)")
    add_params(c, "label", "the labelling parameters (e.g. params.yaml)")
    return p


# --------------------------------------------------------------------------- init


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
            raise UsageError(f"{rel}: matches no --device pattern ({', '.join(g for _, g in patterns)}): "
                               "give --device ID=GLOB for it")
        out[dev].append(rel)
    for dev, got in out.items():
        if not got:
            raise UsageError(f"--device {dev}: its pattern matches no data file")
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
    UsageError
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
        raise UsageError("the devices' files pair up neither by folder, nor by name, nor in order "
                         f"({', '.join(f'{d}: {n} files' for d, n in counts.items())}): put each recording "
                         "in its own folder holding one file per device (or check the --device patterns)")
    n = next(iter(counts.values()))
    return [(f"rec-{k + 1:02d}", {d: by_device[d][k] for d in devices}) for k in range(n)]


@dataclass
class _Device:
    id: str
    role: str
    format: str
    model: str
    entry: dict[str, Any]
    evidence: dict[str, str]
    notes: list[str]


def _device(dev: str, dets: list[Detection], models: dict[str, str]) -> _Device:
    first = dets[0]
    for d in dets[1:]:
        if d.format != first.format:
            raise UsageError(f"{d.path}: format {d.format}, but {first.path.name} of the same device "
                               f"{dev} is {first.format}: give each kind of file its own --device")
        a = first.mapping.to_dict() if first.mapping is not None else first.options
        b = d.mapping.to_dict() if d.mapping is not None else d.options
        if a != b:
            key = next(k for k in list(a) + list(b) if a.get(k) != b.get(k))
            raise UsageError(f"{d.path}: {key} {show_value(b.get(key))}, but {first.path.name} of the same "
                               f"device {dev} has {show_value(a.get(key))}: one device's files must share a "
                               "layout (map them to separate devices or sessions)")
    model = models.get(dev) or first.model or "unknown"
    evidence = {"model": "given with --model" if dev in models else (first.evidence("model") or
                "not in the file: give --model ID=MODEL")}
    entry: dict[str, Any] = dict(first.options)
    if first.mapping is not None:
        entry.update(first.mapping.to_dict())
    same = f" (in {first.path.name}; the {len(dets)} files agree)" if len(dets) > 1 else ""
    for d in first.decisions:
        evidence.setdefault(d.key, d.evidence + same)
    notes = [f"{d.key}: {show_value(d.value)} ({d.evidence})" for d in first.decisions
             if d.key in ("trailing_delimiter", "zero", "decimal_comma")]
    return _Device(dev, "dut", first.format, model, entry, evidence, notes)


def _flow(value: Any) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=10**6, allow_unicode=True, sort_keys=False)
    text = text.strip()
    if text.endswith("..."):
        text = text[:-3].strip()
    return text


def _line(indent: str, key: str, value: Any, why: str | None) -> str:
    out = f"{indent}{key}: {_flow(value)}"
    return out + f"  # {' '.join(why.split())}" if why else out


def manifest_text(top: dict[str, Any], top_why: dict[str, str], devices: list[_Device],
                  recordings: list[tuple[str, dict[str, str]]], file_notes: dict[str, str]) -> str:
    """The manifest as YAML with each decision's evidence as a comment beside its key."""
    out = ["# Written by ofbe-session init from the files in this folder. The comments give the",
           "# evidence of each detected value; edit what is wrong, then run: ofbe-session check <folder>",
           _line("", "format", MANIFEST_FORMAT, None)]
    out += [_line("", k, v, top_why.get(k)) for k, v in top.items()]
    out.append("devices:")
    for d in devices:
        out.append(f"  {d.id}:")
        out += [f"    # {' '.join(n.split())}" for n in d.notes]
        out.append(_line("    ", "model", d.model, d.evidence.get("model")))
        out.append(_line("    ", "role", d.role, d.evidence.get("role")))
        out.append(_line("    ", "format", d.format, d.evidence.get("format")))
        out += [_line("    ", k, v, d.evidence.get(k)) for k, v in d.entry.items()]
    out.append("recordings:")
    for rid, files in recordings:
        out.append(f"  - id: {_flow(rid)}")
        out += [f"    # {rel}: {file_notes[rel]}" for rel in files.values() if file_notes.get(rel)]
        out.append(_line("    ", "files", files, None))
    return "\n".join(out) + "\n"


def _hints(args: argparse.Namespace) -> Hints:
    return Hints(rate_hz=args.rate, acc_unit=args.unit, lsb_per_g=args.lsb_per_g,
                 zero_counts=args.zero_counts, time_unit=args.time_unit, time_column=args.time_column,
                 columns=args.columns)


def _site(args: argparse.Namespace) -> tuple[dict[str, float], str]:
    if args.site:
        try:
            lat, height = (float(x) for x in args.site.split(","))
        except ValueError:
            raise UsageError(f"--site: expected LAT,HEIGHT_M (e.g. 32.794,35), found {args.site!r}"
                               ) from None
        if not (-90 <= lat <= 90 and -500 <= height <= 9000):
            raise UsageError(f"--site: expected a latitude in [-90, 90] and a height in [-500, 9000] m, "
                               f"found {args.site!r}")
        return {"latitude_deg": lat, "height_m": height}, "given with --site"
    if args.gravity is not None:
        if not 9.7 <= args.gravity <= 9.9:
            raise UsageError(f"--gravity: expected m/s² in [9.7, 9.9], found {args.gravity}")
        return {"gravity_mps2": args.gravity}, "given with --gravity"
    return {"gravity_mps2": G0}, "standard gravity: no --site or --gravity given"


def _tilt_warning(det: Detection) -> str | None:
    if det.direction is None or not np.any(det.direction):
        return None
    tilt = math.degrees(math.acos(min(1.0, float(np.max(np.abs(det.direction))))))
    if tilt <= MAX_LEVEL_TILT_DEG:
        return None
    return (f"{det.path}: the mean at rest is {tilt:.1f}° from the nearest axis: not level, so a gravity-"
            "aligned label would be rejected (--kind multi-position for several orientations)")


def _init(args: argparse.Namespace) -> int:
    folder = Path(args.dir)
    if not folder.is_dir():
        return fail(PROG, f"{folder}: expected a session folder holding data files, found no such folder",
                    EXIT_USAGE)
    target = folder / MANIFEST_NAME
    if target.exists() and not args.force:
        return fail(PROG, str(OutputExistsError(target)), EXIT_USAGE)
    try:
        for dev, _ in args.device:
            if not ID_PATTERN.match(dev):
                raise UsageError(f"--device {dev}: expected an id of [A-Za-z0-9._-]+")
        known = [d for d, _ in args.device] or ["dut"]
        for dev, _ in args.model:
            if dev not in known:
                raise UsageError(f"--model {dev}: no such device ({', '.join(known)})")
        if args.reference and args.kind not in (None, "rotated"):
            raise UsageError(f"--reference: a {args.kind} session has no reference device")
        site, site_why = _site(args)
        files, ignored = data_files(folder)
        if not files:
            return fail(PROG, f"{folder}: expected data files ({', '.join(DATA_SUFFIXES)}), found none",
                        EXIT_DATA)
        by_device = assign_devices(files, args.device)
        recordings = group_recordings(by_device)
    except UsageError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    for rel in ignored:
        print(f"ignored: {rel} (not a data file suffix)")
    hints = _hints(args)
    dets: dict[str, Detection] = {}
    for rel in files:
        try:
            det = sniff_text(folder / rel, hints)
        except DetectionError as exc:
            return fail(PROG, str(exc), EXIT_USAGE)
        except OfbeError as exc:
            return fail(PROG, str(exc), EXIT_DATA)
        dets[rel] = det
        print(f"{rel}:")
        for line in det.lines():
            print(f"  {line}")
    models = dict(args.model)
    try:
        devices = [_device(dev, [dets[f] for f in fs], models) for dev, fs in by_device.items()]
    except UsageError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    refs = [d for d in devices if d.format in REFERENCE_FORMATS] if len(devices) > 1 else []
    ref = None
    if args.reference:
        ref = next((d for d in devices if d.id == args.reference), None)
        if ref is None:
            return fail(PROG, f"--reference {args.reference}: no such device ({', '.join(by_device)})",
                        EXIT_USAGE)
        ref.evidence["role"] = "given with --reference"
    elif len(refs) == 1 and args.kind in (None, "rotated"):
        ref = refs[0]
        ref.evidence["role"] = f"{ref.format}: the Memsense reference IMU"
    kind = args.kind or ("rotated" if ref else "gravity-aligned")
    if kind == "rotated" and ref is None:
        return fail(PROG, f"{folder}: kind rotated needs one reference device, found none: give "
                          "--reference ID", EXIT_USAGE)
    if ref is not None and kind == "rotated":
        ref.role = "reference"
        for d in devices:
            if d.role == "dut":
                d.notes.append("reference_to_sensor not given: identity assumed (add it when this device is "
                               "mounted turned relative to the reference)")
    kind_why = ("given with --kind" if args.kind else
                f"{ref.id} is a reference" if ref else "no reference device (--kind to change)")
    session = sanitise(folder.resolve().name)
    campaign = sanitise(folder.resolve().parent.name)
    trailing = re.search(r"(\d+)$", session)
    power_cycle = (args.power_cycle if args.power_cycle is not None else
                   int(trailing.group(1)) if trailing else 0)
    pc_why = ("given with --power-cycle" if args.power_cycle is not None else
              f"the number the session id {session!r} ends with" if trailing else
              "no number in the session id: give --power-cycle N, unique per device within the campaign")
    top = {"campaign": campaign, "session": session, "kind": kind, "site": site, "power_cycle": power_cycle}
    top_why = {"campaign": f"the parent folder {folder.resolve().parent.name!r}",
               "session": f"the folder {folder.resolve().name!r}", "kind": kind_why, "site": site_why,
               "power_cycle": pc_why}
    notes = {rel: "; ".join(f"{k} {show_value(v)}" + (f" ({e})" if k == "rate" else "")
                            for k, v, e in ((d.key, d.value, d.evidence) for d in det.decisions)
                            if k in ("rows", "rate")) for rel, det in dets.items()}
    text = manifest_text(top, top_why, devices, recordings, notes)
    try:
        parse_manifest(target, YamlDocument(text))
    except OfbeError as exc:  # pragma: no cover - a detection bug, not bad input
        return fail(PROG, f"the manifest detected for {folder} does not validate: {exc}", EXIT_DATA)
    warn = [w if w.startswith(str(d.path)) else f"{d.path}: {w}" for d in dets.values() for w in d.warnings]
    if kind == "gravity-aligned":
        warn += [w for w in (_tilt_warning(d) for d in dets.values()) if w]
    if "gravity_mps2" in site and site_why.startswith("standard"):
        warn.append(f"g_local is standard gravity {G0} m/s² (local gravity differs by up to ±0.3 %): give "
                    "--site LAT,HEIGHT_M or --gravity G")
    for w in warn:
        print(f"{PROG}: warning: {w}", file=sys.stderr)
    write_bytes_atomic(target, text.encode("utf-8"))
    roles = ", ".join(f"{d.id} ({d.role}, {d.format})" for d in devices)
    n = len(recordings)
    print(f"wrote {target}: {kind}, {n} recording{'s' if n != 1 else ''}, devices {roles}; "
          f"next: {PROG} check {folder}")
    return EXIT_OK


# --------------------------------------------------------------------------- check


def _units(m: SessionManifest, dev: str, rec: Recording) -> str:
    spec = m.devices[dev]
    if spec.csv is not None:
        c = spec.csv
        t = f"t {c.time_unit}" if "t" in c.columns else f"no t ({fmt_num(c.sample_rate_hz or 0.0)} Hz)"
        acc = c.acc_unit
        if c.acc_unit == "counts":
            acc += f", {show_value(c.lsb_per_g)} per g" + (f", zero {show_value(c.zero_counts)}"
                                                           if np.any(c.zero_axes()) else "")
        return f"{t}, acc {acc}"
    if spec.format == "ofbe-logger":
        return f"t us, acc counts ({rec.header.get('lsb_per_g', '?')} per g)"
    if spec.bin is not None:
        nominal = spec.bin.sample_rate_hz
        base = f" (else {fmt_num(nominal)} Hz)" if nominal else ""
        return f"t from time sub-packets{base}, acc {spec.bin.acc_unit}"
    return "t s, acc g"


def _file_lines(m: SessionManifest, rid: str, dev: str, rec: Recording, labels: SessionLabels
                ) -> tuple[list[str], int]:
    """What ``check`` prints for one file (indented by the caller) and its number of rejections."""
    d = rec.diagnostics
    duration = float(rec.t[-1] - rec.t[0]) if rec.n > 1 else 0.0
    gaps = f"{len(d.gaps)} gap{'s' if len(d.gaps) != 1 else ''}" + (
        f" ({d.missing_samples} samples missing)" if d.gaps else "")
    out = [f"{m.devices[dev].format}: {rec.n} rows, {fmt_num(rec.fs_hz, 5)} Hz, {duration:.2f} s; "
           f"{_units(m, dev, rec)}; {len(d.skipped)} lines skipped, {gaps}"]
    rows = [r for r in labels.rows if r["recording"] == rid and r["device"] == dev]
    if rows:
        mean = np.asarray(rows[0]["_mean"])
        where = "over the stationary segment"
    else:
        window = int(round(rec.fs_hz)) if rec.fs_hz > 2 else 2
        mean = quiet_mean(rec.acc, window)[0] if rec.n >= 2 else np.zeros(3)
        where = "over its quietest second"
    norm = float(np.linalg.norm(mean))
    out.append(f"‖mean‖ {norm:.5g} m/s² = {norm / m.g_local:.4f} × g_local {where}")
    for k, r in enumerate(rows):
        pose = (f"pose {r.get('pose', k)} (‖mean‖ {float(np.linalg.norm(r['_mean'])):.5g} m/s²): "
                if len(rows) > 1 else "")
        b = ", ".join(f"{r[f'bias_{a}']:+.4f}" for a in "xyz")
        t0 = float(rec.t[0]) if rec.n else 0.0
        out.append(f"{pose}stationary {r['segment_start_s'] - t0:.2f}–{r['segment_end_s'] - t0:.2f} s "
                   f"({r['n_samples']} samples): would label, {r['label_method']}, bias [{b}] m/s²")
    bad = [j for j in labels.rejections if j.recording == rid and j.device == dev]
    out += [f"would REJECT ({j.reason}): {j.detail}" for j in bad]
    if m.devices[dev].role == "reference":
        out.append("reference: gives the gravity direction")
    out += [w.split(": ", 1)[1] for w in labels.warnings if w.startswith(f"{rid}/{dev}: ")]
    return out, len(bad)


def _next_pose_lines(m: SessionManifest, labels: SessionLabels, params: Any) -> list[str]:
    """Per DUT with labelled poses: the full model's expected SEs from its poses and the next
    orientations to record (methods.md §8, :func:`ofbe_data.labelling.next_pose.report_lines`)."""
    out: list[str] = []
    for dev in m.duts:
        rows = [r for r in labels.rows if r["device"] == dev.id]
        if not rows:
            continue
        means = np.array([np.asarray(r["_mean"], dtype=np.float64) for r in rows])
        rms = rows[0].get("fit_residual_rms")
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            out += report_lines(dev.id, means, m.g_local, rms,
                                getattr(params, "multi_position_max_condition", 1000.0))
    return out


def _check_one(folder: Path, params: Any) -> bool:
    try:
        m = load_manifest(folder)
    except OfbeError as exc:
        print(f"{folder}: error: {exc}")
        return False
    n = len(m.recordings)
    print(f"{folder}: {m.campaign}/{m.session}, {m.kind}, {n} recording{'s' if n != 1 else ''}, devices "
          f"{', '.join(f'{d.id} ({d.role}, {d.format})' for d in m.devices.values())}; g_local "
          f"{m.g_local:.5f} m/s²")
    recs: dict[tuple[str, str], Recording] = {}
    ok = True
    for r in m.recordings:
        for dev, rel in r.files.items():
            try:
                recs[(r.id, dev)] = read_device_file(m.file_path(r, dev), m.devices[dev])
            except OfbeError as exc:
                print(f"  {r.id}  {dev}  {rel}\n      cannot read: {exc}")
                ok = False
    if not ok:
        print("  → would not label: a file cannot be read")
        return False
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            labels = label_session(folder, params)
    except OfbeError as exc:
        print(f"  labelling fails: {exc}")
        return False
    rejected = 0
    for r in m.recordings:
        for dev, rel in r.files.items():
            print(f"  {r.id}  {dev}  {rel}")
            lines, bad = _file_lines(m, r.id, dev, recs[(r.id, dev)], labels)
            rejected += bad
            print("\n".join(f"      {line}" for line in lines))
    other = [w for w in labels.warnings if not any(w.startswith(f"{r.id}/{d}: ") for r in m.recordings
                                                   for d in r.files)]
    for w in other:
        print(f"  warning: {w}")
    if m.kind == "multi-position":
        for line in _next_pose_lines(m, labels, params):
            print(f"  {line}")
    pairs = len(labels.rows) + rejected
    if rejected or not labels.rows:
        print(f"  → would not label all: {rejected} rejected, {len(labels.rows)} labelled")
        return False
    print(f"  → would label {len(labels.rows)} of {pairs}")
    return True


def _check(args: argparse.Namespace) -> int:
    try:
        data = read_label_section(args.params) if args.params else {}
        params = label_params_from(data, args.params or "command line")
        folders = expand_sessions(args.dirs)
    except OfbeError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    results = [_check_one(f, params) for f in folders]
    return EXIT_OK if all(results) else EXIT_DATA


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """``ofbe-session init|check``; returns the exit status."""
    args = _parser().parse_args(argv)
    return _init(args) if args.cmd == "init" else _check(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
