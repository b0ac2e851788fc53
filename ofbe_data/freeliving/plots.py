"""``ofbe-autocal --plots``: one figure per recording, its still epochs before and after calibration.

``DIR/<file stem>.calibration.png``, one figure of four panels:

- top, three projections of the still epochs' mean vectors (x–y, x–z, y–z, g) with the unit
  circle: before calibration (grey) and after (colour). They show where on the sphere the
  wearer's still moments lie (the coverage the fit needs) and the points pulled onto it;
- bottom, the norm error ‖mean‖ − 1 g of each still epoch, mg, against its temperature, °C
  (against its place in the file when the file has no temperature), before and after: a
  temperature slope shows as a tilt before and none after. In ``--mode ofbe`` the epochs the
  robust fit gave weight 0 (not truly still) are marked.

The title names the file, the mode, the model and the calibration error before → after (GGIR's
``cal.error``, mg), or why the file was not calibrated. A file with no still epoch gets no figure
(the command says so in one line).

The figure is drawn from what the command writes anyway, the summary row and the epochs table
(:mod:`~ofbe_data.freeliving.summary`), so it can be drawn in the worker that calibrated the file
or from an output folder later. "After" applies the written coefficients as the summary's
conventions say (GGIR's: (raw + offset)·scale + (T − temp_mean_c)·temp_offset; ofbe's:
A⁻¹·(raw − b − c·(T − temp_mean_c))); the same inputs give the same PNG bytes
(:func:`ofbe_data.core.figures.save_png`: no time stamp, no software version).
"""

from __future__ import annotations

import tempfile
import textwrap
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.core.figures import STYLE, new_figure, save_png
from ofbe_data.freeliving.ggir import apply_ggir

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MAX_POINTS = 5000
"""Still epochs drawn per series; beyond it every k-th (k the smallest that fits), in file order."""
BEFORE_COLOUR = "#9a9a9a"
AFTER_COLOUR = "#1b9e77"
DOWNWEIGHTED_COLOUR = "#d95f02"
TITLE_CHARS = 100
"""Characters per line of the title (a 9-inch figure holds about 110 at 10 pt)."""
AXES = "xyz"
PROJECTIONS = ((0, 1), (0, 2), (1, 2))
"""The axis pairs of the three projections: x–y, x–z, y–z."""


@dataclass(frozen=True, eq=False)
class CalibrationPlotData:
    """What one recording's figure draws (:func:`plot_data`).

    Attributes
    ----------
    name
        The file's name.
    mode, model
        ``ofbe`` or ``ggir``, and the model as the summary writes it ("" when none was fitted).
    calibrated
        Whether coefficients were applied (False: only "before" is drawn).
    qc
        The summary's ``qc`` line.
    epoch
        Shape (n,): each still epoch's 0-based row in the file.
    before_g
        Shape (n, 3): the still epochs' raw means, g.
    after_g
        Shape (n, 3): the same calibrated with the written coefficients, g; None when not
        calibrated.
    temperature_c
        Shape (n,): their temperatures, °C; None when the file has none.
    downweighted
        Shape (n,), bool: epochs the robust fit gave weight 0 (``--mode ofbe``; none in ggir mode).
    cal_error_start_mg, cal_error_end_mg
        The summary's errors, mg (None where it has none).
    """

    name: str
    mode: str
    model: str
    calibrated: bool
    qc: str
    epoch: np.ndarray
    before_g: np.ndarray
    after_g: np.ndarray | None
    temperature_c: np.ndarray | None
    downweighted: np.ndarray
    cal_error_start_mg: float | None
    cal_error_end_mg: float | None

    @property
    def n(self) -> int:
        """Still epochs drawn."""
        return int(self.epoch.size)

    def norm_error_mg(self, after: bool = False) -> np.ndarray:
        """Shape (n,): ‖mean‖ − 1 g of each still epoch, mg, before (or after) calibration.

        Raises
        ------
        ValueError
            ``after`` for a recording that was not calibrated.
        """
        v = self.after_g if after else self.before_g
        if v is None:
            raise ValueError(f"{self.name}: expected a calibrated recording for the error after, found none")
        return (np.sqrt(np.sum(v * v, axis=1)) - 1.0) * 1000.0


def _value(row: Mapping[str, object], name: str) -> float | None:
    value = row.get(name)
    return None if value is None or value == "" else float(value)  # type: ignore[arg-type]


def _vector(row: Mapping[str, object], names: list[str], default: float | None) -> np.ndarray | None:
    values = [_value(row, n) for n in names]
    if any(v is None for v in values):
        return None if default is None else np.full(len(names), default)
    return np.array(values, dtype=np.float64)


def calibrated_means(row: Mapping[str, object], means_g: np.ndarray,
                     temperature_c: np.ndarray | None) -> np.ndarray | None:
    """Raw means calibrated with a summary row's coefficients, as its conventions say.

    Parameters
    ----------
    row
        A summary row (:func:`~ofbe_data.freeliving.summary.summary_row`, or a ``summary.csv``
        line read as strings).
    means_g
        Shape (n, 3): raw means, g.
    temperature_c
        Shape (n,): their temperatures, °C, or None.

    Returns
    -------
    np.ndarray or None
        Shape (n, 3), g; None when the row is not calibrated.
    """
    if str(row.get("calibrated")).lower() != "true":
        return None
    m = np.asarray(means_g, dtype=np.float64)
    t_ref = _value(row, "temp_mean_c")
    if row.get("mode") == "ggir":
        scale = _vector(row, [f"scale_{a}" for a in AXES], None)
        offset = _vector(row, [f"offset_{a}" for a in AXES], None)
        slope = _vector(row, [f"temp_offset_{a}" for a in AXES], 0.0)
        if scale is None or offset is None or slope is None:
            raise ValueError(f"{row.get('file')}: expected GGIR's scale and offset in a calibrated row, "
                             "found empty columns")
        return apply_ggir(m, temperature_c if t_ref is not None else None, scale, offset, slope, t_ref)
    b = _vector(row, [f"ofbe_offset_{a}" for a in AXES], None)
    if b is None:
        raise ValueError(f"{row.get('file')}: expected ofbe_offset_x/y/z in a calibrated row, "
                         "found empty columns")
    a_map = _vector(row, [f"a_{r}{c}" for r in AXES for c in AXES], None)
    a_map = np.eye(3) if a_map is None else a_map.reshape(3, 3)
    c = _vector(row, [f"ofbe_temp_slope_{a}" for a in AXES], None)
    drift = 0.0
    if c is not None and t_ref is not None and temperature_c is not None:
        drift = (np.asarray(temperature_c, dtype=np.float64) - t_ref)[:, None] * c
    return np.linalg.solve(a_map, (m - b - drift).T).T


def plot_data(row: Mapping[str, object], epochs: pa.Table | bytes) -> CalibrationPlotData | None:
    """What a recording's figure draws, from its summary row and its epochs table.

    Parameters
    ----------
    row
        The recording's summary row.
    epochs
        Its epochs table (:data:`~ofbe_data.freeliving.summary.EPOCH_SCHEMA`), or the bytes of its
        ``.epochs.parquet`` file.

    Returns
    -------
    CalibrationPlotData or None
        None when the recording has no still epoch.
    """
    table = pq.read_table(pa.BufferReader(epochs)) if isinstance(epochs, bytes | bytearray) else epochs
    data = table.to_pydict()
    still = ~np.asarray(data["idle"], dtype=bool)
    if not still.any():
        return None
    means = np.column_stack([np.asarray(data[f"mean_{a}"], dtype=np.float64) for a in AXES])[still]
    temps = np.array([np.nan if t is None else t for t in data["temperature_c"]], dtype=np.float64)[still]
    temps_or_none = temps if np.all(np.isfinite(temps)) else None
    weight = np.array([np.nan if w is None else w for w in data["weight"]], dtype=np.float64)[still]
    used = np.asarray(data["used"], dtype=bool)[still]
    return CalibrationPlotData(
        name=Path(str(row.get("file", ""))).name, mode=str(row.get("mode") or ""),
        model=str(row.get("model") or ""),
        calibrated=str(row.get("calibrated")).lower() == "true", qc=str(row.get("qc") or ""),
        epoch=np.asarray(data["epoch"], dtype=np.int64)[still], before_g=means,
        after_g=calibrated_means(row, means, temps_or_none), temperature_c=temps_or_none,
        downweighted=used & (weight == 0.0), cal_error_start_mg=_value(row, "cal_error_start_mg"),
        cal_error_end_mg=_value(row, "cal_error_end_mg"))


def _model_words(d: CalibrationPlotData) -> str:
    """``full+temperature model`` (the summary's model less its mode), or ``no model fitted``."""
    model = d.model.removeprefix(f"{d.mode} ").strip()
    return f"{model} model" if model else "no model fitted"


def _title(d: CalibrationPlotData) -> str:
    head = textwrap.shorten(f"{d.name}: {d.mode} mode, {_model_words(d)}, {d.n:,} still epochs", TITLE_CHARS,
                            placeholder=" …")
    if d.calibrated and d.cal_error_start_mg is not None and d.cal_error_end_mg is not None:
        tail = f"calibration error {d.cal_error_start_mg:.3f} → {d.cal_error_end_mg:.3f} mg"
    else:
        tail = f"not calibrated: {d.qc}"
    text = head + "\n" + textwrap.fill(tail, width=TITLE_CHARS, max_lines=2, placeholder=" …")
    return text.replace("$", r"\$")  # a file name's $ is text, not mathtext


def _every(n: int) -> int:
    return max(1, -(-n // MAX_POINTS))


def draw_calibration(d: CalibrationPlotData) -> Figure:
    """The figure of one recording (module notes), not yet saved.

    Parameters
    ----------
    d
        What to draw (:func:`plot_data`).

    Returns
    -------
    Figure
        Five panels: three projections of the still epochs (g), then their norm error (mg)
        against temperature (°C) before and, beside it on its own scale, after calibration.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, axes = new_figure(2, 3, width_in=9.0, height_in=7.0, gridspec_kw={"height_ratios": [1.0, 0.9]})
    step = _every(d.n)
    pick = slice(None, None, step)
    before = d.before_g[pick]
    after = d.after_g[pick] if d.after_g is not None else None
    circle = np.linspace(0.0, 2.0 * np.pi, 361)
    x = d.temperature_c if d.temperature_c is not None else d.epoch.astype(np.float64)
    x_label = "temperature (°C)" if d.temperature_c is not None else "epoch (row of the file)"
    with plt.rc_context(STYLE):
        for ax, (i, j) in zip(axes[0], PROJECTIONS, strict=True):
            ax.plot(np.cos(circle), np.sin(circle), color="black", lw=0.8, ls="--", label="1 g")
            ax.plot(before[:, i], before[:, j], ".", ms=2.0, color=BEFORE_COLOUR, label="before")
            if after is not None:
                ax.plot(after[:, i], after[:, j], ".", ms=2.0, color=AFTER_COLOUR, label="after")
            ax.set_xlim(-1.3, 1.3)
            ax.set_ylim(-1.3, 1.3)
            ax.set_aspect("equal")
            ax.set_xlabel(f"{AXES[i]} (g)")
            ax.set_ylabel(f"{AXES[j]} (g)")
            ax.set_title(f"still epochs, {AXES[i]}–{AXES[j]} projection", fontsize=10)
        axes[0][2].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), markerscale=4, fontsize=8)
        grid = axes[1][0].get_gridspec()
        for ax in axes[1]:
            ax.remove()
        halves = grid[1, :].subgridspec(1, 2)
        ax_before = fig.add_subplot(halves[0])
        ax_after = fig.add_subplot(halves[1], sharex=ax_before)
        drawn = f"; 1 in {step} drawn" if step > 1 else ""
        err = d.norm_error_mg()
        ax_before.plot(x[pick], err[pick], ".", ms=2.5, color=BEFORE_COLOUR,
                       label=f"mean |error| {np.mean(np.abs(err)):.3f} mg")
        ax_before.set_title(f"before calibration ({d.n:,} still epochs{drawn})", fontsize=10)
        if d.after_g is not None:
            err = d.norm_error_mg(after=True)
            ax_after.plot(x[pick], err[pick], ".", ms=2.5, color=AFTER_COLOUR,
                          label=f"{_model_words(d)}: mean |error| {np.mean(np.abs(err)):.3f} mg")
            low = d.downweighted[pick]
            if low.any():
                ax_after.plot(x[pick][low], err[pick][low], "x", ms=4.0, color=DOWNWEIGHTED_COLOUR,
                              label="weight 0 in the robust fit")
            ax_after.set_title("after calibration (its own scale)", fontsize=10)
            ax_after.legend(loc="best", markerscale=2, fontsize=8)
        else:
            ax_after.text(0.5, 0.5, "not calibrated:\nno coefficients applied", transform=ax_after.transAxes,
                          ha="center", va="center", color="0.3")
            ax_after.set_title("after calibration", fontsize=10)
            ax_after.set_yticks([])
        for ax in (ax_before, ax_after):
            ax.xaxis.set_major_locator(MaxNLocator(nbins=6))
            ax.set_xlabel(x_label)
            if ax is ax_before or d.after_g is not None:
                ax.axhline(0.0, color="black", lw=0.8)
                ax.set_ylabel("‖mean‖ − 1 g (mg)")
        ax_before.legend(loc="best", markerscale=3, fontsize=8)
        fig.suptitle(_title(d), fontsize=10)
    return fig


def calibration_png(row: Mapping[str, object], epochs: pa.Table | bytes) -> bytes | None:
    """The PNG bytes of a recording's figure, or None when it has no still epoch.

    Written through :func:`~ofbe_data.core.figures.save_png` (into a temporary folder, since a
    worker returns the bytes to the command, which writes every output): the same inputs give
    the same bytes.
    """
    d = plot_data(row, epochs)
    if d is None:
        return None
    with warnings.catch_warnings():
        # a character of a file name that the font lacks is drawn as a box, not warned about
        warnings.filterwarnings("ignore", message="Glyph .* missing from", category=UserWarning)
        fig = draw_calibration(d)
        with tempfile.TemporaryDirectory(prefix="ofbe-autocal-plot-") as tmp:
            return save_png(fig, Path(tmp) / "figure.png").read_bytes()


__all__ = ["CalibrationPlotData", "calibrated_means", "calibration_png", "draw_calibration", "plot_data"]

