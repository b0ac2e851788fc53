"""``ofbe-session check`` (:mod:`ofbe_data.cli.session`): each session validated, every file
read and labelling run in memory (nothing is written), and per file what was found and what
labelling would reject and why (:func:`check`). Imported when the subcommand runs, after
parsing (docs/architecture.md, "Command lines").
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, fail
from ofbe_data.core.errors import OfbeError
from ofbe_data.io.detection import fmt_num, quiet_mean, show_value
from ofbe_data.io.manifest import MANIFEST_NAME, SessionManifest, load_manifest
from ofbe_data.io.recording import Recording
from ofbe_data.labelling.batch import expand_sessions, skipped_folders
from ofbe_data.labelling.labels import (
    SessionLabels,
    label_params_from,
    label_session,
    read_hashed,
    read_label_section,
)
from ofbe_data.labelling.multiposition import labelled_fit, noise_of_rows, report_lines

PROG = "ofbe-session"


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


def check(args: argparse.Namespace) -> int:
    """``ofbe-session check DIR...``: every session validated, read and labelled in memory, what
    labelling would do printed; returns the exit status."""
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
