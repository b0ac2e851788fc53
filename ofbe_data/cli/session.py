"""``ofbe-session``: write a session's manifest from its files (``init``), and check a session
before labelling it (``check``).

``init DIR`` detects each file's format, columns, units and rate (:mod:`ofbe_data.io.detection`),
prints every decision with its evidence (the rate as ``check`` reports it), and writes
``DIR/session.yaml`` with the evidence as YAML comments beside the keys. A file with two
accelerometer triads gives two devices naming it; ``power_cycle`` comes only from an explicit
pattern of the folder's name (``pc3``…), else 1 with a warning. A case the files do not settle
stops with the flag to give. The folder's files, devices and recordings are found by
:mod:`ofbe_data.io.detection`; the YAML with its evidence is :mod:`ofbe_data.cli.session_init`'s.

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
import math
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.cli.session_init import manifest_text
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, add_params, command, fail, with_examples
from ofbe_data.core.errors import OfbeError, OutputExistsError
from ofbe_data.io.detection import (
    DATA_SUFFIXES,
    Detection,
    DetectionError,
    Hints,
    SessionFilesError,
    assign_devices,
    data_files,
    fmt_num,
    group_recordings,
    init_devices,
    power_cycle_of,
    quiet_mean,
    sanitise,
    show_value,
    sniff_text,
)
from ofbe_data.io.device_options import COLUMN_KEYS, GYRO_KEYS, GYRO_UNITS
from ofbe_data.io.formats import reference_formats
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import (
    ACC_UNITS,
    ID_PATTERN,
    KINDS,
    MANIFEST_NAME,
    TIME_UNITS,
    SessionManifest,
    load_manifest,
    parse_manifest,
)
from ofbe_data.io.recording import Recording
from ofbe_data.io.yamlio import YamlDocument
from ofbe_data.labelling.batch import UsageError, expand_sessions, skipped_folders
from ofbe_data.labelling.checks import MAX_LEVEL_TILT_DEG
from ofbe_data.labelling.labels import (
    SessionLabels,
    label_params_from,
    label_session,
    read_hashed,
    read_label_section,
)
from ofbe_data.labelling.multiposition import labelled_fit, noise_of_rows, report_lines

PROG = "ofbe-session"


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
    bad = [k for k in out if k not in COLUMN_KEYS]
    gyro = [k for k in GYRO_KEYS if k in out]
    if bad or not {"ax", "ay", "az"} <= set(out) or len(gyro) not in (0, 3):
        raise argparse.ArgumentTypeError("expected t=…,ax=…,ay=…,az=…[,temperature=…][,gx=…,gy=…,gz=…], "
                                         f"found {text!r}")
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
                   "per device (default: every file to one device 'dut'; files holding two accelerometer "
                   "triads give two devices, ID-1 and ID-2, that read the same files)")
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
                   "with --rate; gx=,gy=,gz= map the angular rate")
    i.add_argument("--gyro-unit", choices=GYRO_UNITS, help="unit of the angular-rate columns (default: "
                   "from their names or values; left unmapped when neither says)")
    site = i.add_mutually_exclusive_group()
    site.add_argument("--site", metavar="LAT,HEIGHT_M", help="latitude (degrees) and height (m) of the "
                      "site: local gravity from WGS-84")
    site.add_argument("--gravity", type=float, metavar="G", help="local gravity, m/s²")
    i.add_argument("--power-cycle", type=int, metavar="N", help="bias-instance id (default: the number of "
                   "an explicit pattern in the session folder's name, pc3, pc-003, power_cycle_3 or cycle3; "
                   "else 1, with a warning: other digits are usually a model number)")
    i.add_argument("--force", action="store_true", help="replace an existing session.yaml")
    c = sub.add_parser("check", help="validate sessions and say what labelling would do",
                       description="Validate each session, read every file and run labelling in memory "
                       "(nothing is written); print per file the format, rows, rate, duration, units, "
                       "‖mean‖ against g_local, the stationary segment or poses, and what labelling would "
                       "reject and why. Exit 0 when every recording would be labelled.")
    c.add_argument("dirs", nargs="+", help="session folders (or campaign folders of sessions)")
    add_params(c, "label", "the labelling parameters (e.g. params.yaml)")
    with_examples(i, "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --site 48.15,520",
                  "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --rate 100 --unit g   # "
                  "no time column",
                  "ofbe-session init mine/raw/lab/unit-07 --kind rotated --reference memsense --force")
    with_examples(c, "ofbe-session check mine/raw/lab/unit-07",
                  "ofbe-session check mine/raw/lab --params params.yaml      # every session, the pipeline's "
                  "settings")
    return with_examples(p, "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --site 48.15,520",
                         "ofbe-session check mine/raw/lab/unit-07")


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
    """Per DUT with labelled poses: the model the label writes with its standard errors and why
    (the label's own columns, so that check and label agree), and the next orientations to record
    (methods.md §8, :func:`ofbe_data.labelling.multiposition.report_lines`), expected with the label's own
    error model."""
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
                                getattr(params, "multi_position_max_condition", 1000.0),
                                fitted=labelled_fit(rows[0]), noise=noise_of_rows(rows))
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
    read: dict[tuple[str, str], tuple[Recording, str]] = {}  # each file read once, labelled from here
    ok = True
    for r in m.recordings:
        for dev, rel in r.files.items():
            try:
                read[(r.id, dev)] = read_hashed(m.file_path(r, dev), m.devices[dev])
            except OfbeError as exc:
                print(f"  {r.id}  {dev}  {rel}\n      cannot read: {exc}")
                ok = False
    if not ok:
        print("  → would not label: a file cannot be read")
        return False
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            labels = label_session(folder, params, manifest=m, read=read)
    except OfbeError as exc:
        print(f"  labelling fails: {exc}")
        return False
    rejected = 0
    for r in m.recordings:
        for dev, rel in r.files.items():
            print(f"  {r.id}  {dev}  {rel}")
            lines, bad = _file_lines(m, r.id, dev, read[(r.id, dev)][0], labels)
            rejected += bad
            print("\n".join(f"      {line}" for line in lines))
    other = [w for w in labels.warnings if not any(w.startswith(f"{r.id}/{d}: ") for r in m.recordings
                                                   for d in r.files)]
    for w in other:
        print(f"  warning: {w}")
    for note in labels.notes:  # information (poses found, threshold), not a warning
        print(f"  {note}")
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
    for folder in skipped_folders(args.dirs):
        print(f"{PROG}: note: {folder}: no {MANIFEST_NAME} in it, not a session (skipped)", file=sys.stderr)
    results = [_check_one(f, params) for f in folders]
    for line in shared_power_cycles(folders):
        print(f"{PROG}: warning: {line}", file=sys.stderr)
    return EXIT_OK if all(results) else EXIT_DATA


def shared_power_cycles(folders: Sequence[Path]) -> list[str]:
    """One line per device that several of the sessions checked together put in one power cycle.

    Recordings of one power cycle share one zero-g offset: the campaign fit and the exports treat
    them as one (``ofbe-export json`` refuses two offsets for one power cycle). Two sessions left at
    ``power_cycle: 1`` (``init``'s default when a name says nothing) are the usual cause; one power
    cycle recorded in two session folders is legitimate, hence a warning.
    """
    seen: dict[tuple[str, int, str], list[str]] = {}
    for folder in folders:
        try:
            m = load_manifest(folder)
        except OfbeError:
            continue  # _check_one has said why
        for dev in m.duts:
            seen.setdefault((m.campaign, m.power_cycle, dev.id), []).append(m.session)
    return [f"sessions {', '.join(sessions)} of campaign {campaign} all say power_cycle {pc} for device "
            f"{dev}: "
            "their recordings are taken to share one zero-g offset; if the device was switched off between "
            "them, give each session its own power_cycle in its session.yaml"
            for (campaign, pc, dev), sessions in sorted(seen.items()) if len(sessions) > 1]


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """``ofbe-session init|check``; returns the exit status."""
    args = _parser().parse_args(argv)
    return _init(args) if args.cmd == "init" else _check(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
