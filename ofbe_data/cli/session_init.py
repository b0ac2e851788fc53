"""``ofbe-session init`` (:mod:`ofbe_data.cli.session`): the manifest written from a folder's
files (:func:`init`), as YAML with each decision's evidence as a comment beside its key
(:func:`manifest_text`). What the folder's files are (data files, devices, recordings, the power
cycle) is found by :mod:`ofbe_data.io.detection`. Imported when the subcommand runs, after
parsing (docs/architecture.md, "Command lines").
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, fail
from ofbe_data.core.errors import OfbeError, OutputExistsError
from ofbe_data.io.detection import (
    DATA_SUFFIXES,
    Detection,
    DetectionError,
    DeviceEntry,
    Hints,
    SessionFilesError,
    assign_devices,
    data_files,
    group_recordings,
    init_devices,
    power_cycle_of,
    sanitise,
    show_value,
    sniff_text,
)
from ofbe_data.io.formats import reference_formats
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import ID_PATTERN, MANIFEST_FORMAT, MANIFEST_NAME, parse_manifest
from ofbe_data.io.yamlio import YamlDocument
from ofbe_data.labelling.batch import UsageError
from ofbe_data.labelling.checks import MAX_LEVEL_TILT_DEG

PROG = "ofbe-session"


def _flow(value: Any) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=10**6, allow_unicode=True, sort_keys=False)
    text = text.strip()
    if text.endswith("..."):
        text = text[:-3].strip()
    return text


def _line(indent: str, key: str, value: Any, why: str | None) -> str:
    out = f"{indent}{key}: {_flow(value)}"
    return out + f"  # {' '.join(why.split())}" if why else out


def manifest_text(top: dict[str, Any], top_why: dict[str, str], devices: list[DeviceEntry],
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
        shared = dict.fromkeys(files.values())  # devices reading one file share its note
        out += [f"    # {rel}: {file_notes[rel]}" for rel in shared if file_notes.get(rel)]
        out.append(_line("    ", "files", files, None))
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- init


def _hints(args: argparse.Namespace) -> Hints:
    return Hints(rate_hz=args.rate, acc_unit=args.unit, lsb_per_g=args.lsb_per_g,
                 zero_counts=args.zero_counts, time_unit=args.time_unit, time_column=args.time_column,
                 columns=args.columns, gyro_unit=args.gyro_unit)


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


def _tilt_warning(path: Path, direction: np.ndarray | None, device: str) -> str | None:
    if direction is None or not np.any(direction):
        return None
    tilt = math.degrees(math.acos(min(1.0, float(np.max(np.abs(direction))))))
    if tilt <= MAX_LEVEL_TILT_DEG:
        return None
    return (f"{path} ({device}): the mean at rest is {tilt:.1f}° from the nearest axis: not level, so a "
            "gravity-aligned label would be rejected (--kind multi-position for several orientations)")


def init(args: argparse.Namespace) -> int:
    """``ofbe-session init DIR``: detect the files, print each decision with its evidence and write
    ``DIR/session.yaml``; returns the exit status."""
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
            if dev not in known and not any(dev.startswith(k + "-") for k in known):
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
    except (UsageError, SessionFilesError) as exc:
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
        devices, ids = init_devices(by_device, dets, models)
    except SessionFilesError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    recordings = [(rid, {sub: rel for dev, rel in files_of.items() for sub in ids[dev]})
                  for rid, files_of in recordings]
    refs = [d for d in devices if d.format in reference_formats()] if len(devices) > 1 else []
    ref = None
    if args.reference:
        ref = next((d for d in devices if d.id == args.reference), None)
        if ref is None:
            listed = ", ".join(d.id for d in devices)
            return fail(PROG, f"--reference {args.reference}: no such device ({listed})", EXIT_USAGE)
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
    found: int | None = None
    if args.power_cycle is not None:
        power_cycle, pc_why = args.power_cycle, "given with --power-cycle"
    else:
        found, pc_why = power_cycle_of(session)
        power_cycle = 1 if found is None else found
    top = {"campaign": campaign, "session": session, "kind": kind, "site": site, "power_cycle": power_cycle}
    top_why = {"campaign": f"the parent folder {folder.resolve().parent.name!r}",
               "session": f"the folder {folder.resolve().name!r}", "kind": kind_why, "site": site_why,
               "power_cycle": pc_why}
    print("session:")
    for key, value in top.items():
        print(f"  {key}: {show_value(value)} ({top_why[key]})")
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
        for rel, det in dets.items():
            dev = next(dev for dev, fs in by_device.items() if rel in fs)
            pairs = ([(sub, p.direction) for sub, p in zip(ids[dev], det.parts, strict=True)]
                     if det.format == "csv" else [(dev, det.direction)])
            warn += [w for w in (_tilt_warning(det.path, direction, sub) for sub, direction in pairs) if w]
    if args.power_cycle is None and found is None:
        warn.append(f"power_cycle {power_cycle}: {pc_why}")
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
