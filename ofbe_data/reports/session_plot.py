"""One figure per labelled session (``ofbe-label --plots``): what the labeller used, at a glance.

For every DUT file of the session, two stacked panels over the recording's own time: the
norm ‖f‖ with the local gravity as a dashed line, and the three axes. Every stationary
interval that became a label is shaded and numbered with its ``pose`` (several per file in
a multi-position recording); a file with no label says why in its title. A person checks
the detected poses here instead of annotating them by hand (imucal needs its GUI for that).
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import OfbeError
from ofbe_data.core.figures import new_figure, save_png
from ofbe_data.io.formats import read_device_file
from ofbe_data.labelling.labels import SessionLabels

MAX_FILES = 8
"""Files drawn per session figure (the first ones, in manifest order)."""
MAX_POINTS = 20_000
"""Samples drawn per line (evenly decimated beyond it; the shading is exact)."""
AXIS_COLOURS = ("#1b9e77", "#d95f02", "#7570b3")
NORM_SPAN = 2.0
"""Half-height of the norm panel around g_local, m/s² (a resting norm stays well inside)."""


def _decimate(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_POINTS))


TITLE_CHARS = 80
"""Characters per line of a panel title: an 8-inch panel holds about 95 at 10 pt."""


def _title(rec_id: str, dev_id: str, rows: Sequence[dict[str, Any]], reasons: Sequence[str]) -> str:
    if rows:
        what = f"{len(rows)} pose{'s' if len(rows) != 1 else ''} labelled"
    else:
        what = "not labelled"
    if reasons:
        shown = "; ".join(reasons[:2]) + (f"; {len(reasons) - 2} more" if len(reasons) > 2 else "")
        what += f" — rejected: {shown}"
    return textwrap.fill(f"{rec_id} / {dev_id}: {what}", width=TITLE_CHARS, max_lines=3, placeholder=" …")


def plot_session(labels: SessionLabels, path: str | Path) -> Path:
    """Draw a labelled session's files with their labelled intervals shaded and numbered.

    Parameters
    ----------
    labels
        The session's labels (rows carry ``recording``, ``device``, ``pose``,
        ``segment_start_s`` and ``segment_end_s``, s on the device's clock).
    path
        PNG to write (atomically).

    Returns
    -------
    Path
        The written figure.
    """
    m = labels.manifest
    pairs = [(r.id, d.id) for r in m.recordings for d in m.duts if d.id in r.files][:MAX_FILES]
    fig, axes = new_figure(2 * len(pairs), 1, width_in=8.0, height_in=0.6 + 3.2 * len(pairs), squeeze=False,
                           sharex=False)
    for k, (rec_id, dev_id) in enumerate(pairs):
        ax_norm, ax_xyz = axes[2 * k, 0], axes[2 * k + 1, 0]
        rows = sorted((r for r in labels.rows if r["recording"] == rec_id and r["device"] == dev_id),
                      key=lambda r: r.get("pose", 0))
        reasons = [f"{j.reason}" + (f" ({j.detail[:60]}…)" if len(j.detail) > 60 else f" ({j.detail})")
                   for j in labels.rejections if j.recording == rec_id and j.device == dev_id]
        ax_norm.set_title(_title(rec_id, dev_id, rows, reasons), loc="left", pad=16)
        try:
            rec = read_device_file(m.file_path(next(r for r in m.recordings if r.id == rec_id), dev_id),
                                   m.devices[dev_id])
        except OfbeError as exc:
            ax_norm.text(0.5, 0.5, f"cannot read: {exc}"[:120], transform=ax_norm.transAxes, ha="center")
            continue
        t0 = float(rec.t[0])
        s = _decimate(rec.n)
        t = rec.t[s] - t0
        ax_norm.plot(t, np.sqrt(np.sum(rec.acc[s] ** 2, axis=1)), color="0.2", lw=0.7)
        ax_norm.axhline(m.g_local, color="0.5", ls="--", lw=0.8, label=f"g_local\n{m.g_local:.4f} m/s²")
        for i in range(3):
            ax_xyz.plot(t, rec.acc[s, i], color=AXIS_COLOURS[i], lw=0.7, label="xyz"[i])
        for r in rows:
            a, b = r["segment_start_s"] - t0, r["segment_end_s"] - t0
            for ax in (ax_norm, ax_xyz):
                ax.axvspan(a, b, color="#4daf4a", alpha=0.18, lw=0)
            ax_norm.annotate(str(r.get("pose", 0)), ((a + b) / 2, 1.0), xycoords=("data", "axes fraction"),
                             ha="center", va="bottom", fontsize=9, fontweight="bold", color="#2b7a2b")
        ax_norm.set_ylim(m.g_local - NORM_SPAN, m.g_local + NORM_SPAN)  # motion shows as clipped spikes
        ax_norm.set_ylabel("‖f‖ (m/s²)")
        ax_xyz.set_ylabel("f (m/s²)")
        ax_xyz.set_xlabel("time from the first sample (s); shaded: labelled intervals, numbered by pose")
        ax_norm.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax_xyz.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(f"{m.campaign} / {m.session} ({m.kind})", x=0.01, ha="left", fontsize=12)
    return save_png(fig, path)
