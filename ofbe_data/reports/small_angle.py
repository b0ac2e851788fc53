"""``ofbe-small-angle``: the paper's small-angle figure and its numbers (§4).

Writes into ``--out`` (default ``reports/small_angle``), each file atomically:

- ``small_angle.json``: DVC metrics (format ``ofbe-small-angle/1``): the limit, the threshold
  angle per tilt direction, the closed form asin(limit) and its value, the grid and the
  measure. Byte-identical across runs (sorted keys, floats rounded to fixed decimals).
- ``small_angle.png``: filled contour of the gravity leak (mg) over roll × pitch with the
  limit contour and the single-axis threshold marked.
- ``small_angle_profile.png`` and ``small_angle_profile.csv`` (``tilt_deg,leak_mg``; DVC
  plots): the leak against a single-axis tilt from 0 to the grid range.
- ``small_angle.md``: a short readable report.

The maths is in :mod:`ofbe_data.labelling.smallangle`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.ticker import MaxNLocator

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.figures import new_figure, save_png
from ofbe_data.labelling.smallangle import (
    DIRECTIONS,
    Measure,
    SmallAngleResult,
    analyse,
    leak_g,
    threshold_angle,
)
from ofbe_data.reports.defaults import SMALL_ANGLE_OUT

FORMAT = "ofbe-small-angle/1"
"""Format tag of ``small_angle.json``."""
DEFAULT_OUT = SMALL_ANGLE_OUT
JSON_NAME = "small_angle.json"
PNG_NAME = "small_angle.png"
PROFILE_PNG_NAME = "small_angle_profile.png"
PROFILE_CSV_NAME = "small_angle_profile.csv"
MD_NAME = "small_angle.md"

MAX_GRID_POINTS = 4001
"""Largest grid per axis (4001² leak values ≈ 0.4 GB of intermediates)."""

_DECIMALS = 6  # floats in the JSON are rounded to this many decimals


def _r(x: float) -> float:
    """A float rounded for the JSON (fixed decimals, so the text is stable)."""
    return round(float(x), _DECIMALS)


def metrics(result: SmallAngleResult, range_deg: float, step_deg: float) -> dict[str, Any]:
    """The content of ``small_angle.json``.

    Parameters
    ----------
    result
        The analysis.
    range_deg, step_deg
        The grid options as given.

    Returns
    -------
    dict
        JSON-ready; angles in degrees, leaks in mg.
    """
    other: Measure = "norm" if result.measure == "max-axis" else "max-axis"
    return {
        "format": FORMAT,
        "measure": result.measure,
        "limit_mg": _r(result.limit_g * 1000.0),
        "threshold_deg": {d: _r(result.threshold_deg[d]) for d in DIRECTIONS},
        f"threshold_deg_{other.replace('-', '_')}": {
            d: _r(threshold_angle(result.limit_g, d, other)) for d in DIRECTIONS},
        "formula": "degrees(asin(limit_g))",
        "formula_deg": _r(result.asin_limit_deg),
        "grid": {"range_deg": _r(range_deg), "step_deg": _r(step_deg),
                 "n_points": int(result.roll_deg.size)},
        "max_leak_mg": _r(float(result.surface_g.max()) * 1000.0),
    }


def profile(range_deg: float, step_deg: float, measure: Measure) -> tuple[np.ndarray, np.ndarray]:
    """Leak against a single-axis (pitch) tilt.

    Parameters
    ----------
    range_deg, step_deg
        The tilt runs from 0 to ``range_deg`` in about ``step_deg`` steps (ends exact).
    measure
        Leak measure.

    Returns
    -------
    tilt_deg, leak_mg
        (T,) tilt, degrees, and (T,) leak, mg.
    """
    n = max(1, int(round(range_deg / step_deg))) + 1
    tilt = np.linspace(0.0, range_deg, n)
    return tilt, leak_g(0.0, tilt, measure) * 1000.0


def profile_csv(tilt_deg: np.ndarray, leak_mg: np.ndarray) -> bytes:
    """``tilt_deg,leak_mg`` CSV text with fixed decimals."""
    lines = ["tilt_deg,leak_mg"]
    lines += [f"{t:.4f},{v:.6f}" for t, v in zip(tilt_deg, leak_mg, strict=True)]
    return ("\n".join(lines) + "\n").encode("utf-8")


def _measure_label(measure: str) -> str:
    return "largest per-axis leak" if measure == "max-axis" else "leak vector norm"


def surface_figure(result: SmallAngleResult, path: Path) -> Path:
    """Filled contour of the leak (mg) over roll × pitch, with the limit contour."""
    fig, ax = new_figure(width_in=6.4, height_in=5.4)
    leak_mg = result.surface_g * 1000.0
    limit_mg = result.limit_g * 1000.0
    top = float(leak_mg.max())
    levels = MaxNLocator(nbins=20).tick_values(0.0, top if top > 0 else 1.0)
    filled = ax.contourf(result.roll_deg, result.pitch_deg, leak_mg, levels=levels, cmap="viridis")
    cbar = fig.colorbar(filled, ax=ax)
    cbar.set_label(f"{_measure_label(result.measure)} of a levelled calibration (mg)")
    if limit_mg < top:
        line = ax.contour(result.roll_deg, result.pitch_deg, leak_mg, levels=[limit_mg],
                          colors="white", linewidths=1.6)
        ax.clabel(line, fmt={limit_mg: f"{limit_mg:g} mg"}, fontsize=9, inline=True)
        cbar.ax.axhline(limit_mg, color="white", linewidth=1.6)
    t = result.threshold_deg["pitch"]
    r_range = float(result.roll_deg[-1])
    if t <= r_range:
        ax.plot([0.0, 0.0, t, -t], [t, -t, 0.0, 0.0], linestyle="none", marker="o", markersize=5,
                color="red", label=f"single-axis threshold ±{t:.3f}°")
        ax.annotate(f"{t:.3f}°", xy=(0.0, t), xytext=(0.6, t + 0.08 * r_range), color="red",
                    fontsize=9, arrowprops={"arrowstyle": "-", "color": "red"})
        ax.legend(loc="lower left", frameon=True, facecolor="white", framealpha=0.85, edgecolor="none")
    ax.set_xlabel("roll (deg)")
    ax.set_ylabel("pitch (deg)")
    ax.set_aspect("equal")
    ax.grid(False)
    ax.set_title(f"Levelled-calibration gravity leak ({limit_mg:g} mg at ±{t:.2f}°)")
    return save_png(fig, path)


def profile_figure(tilt_deg: np.ndarray, leak_mg: np.ndarray, threshold_deg: float, limit_mg: float,
                   measure: str, path: Path) -> Path:
    """Leak against a single-axis tilt, with the limit line and the threshold."""
    fig, ax = new_figure(width_in=6.4, height_in=4.0)
    ax.plot(tilt_deg, leak_mg, color="C0", label=f"{_measure_label(measure)} (= 1000·sin tilt)"
            if measure == "max-axis" else _measure_label(measure))
    ax.axhline(limit_mg, color="C3", linestyle="--", linewidth=1.2, label=f"limit {limit_mg:g} mg")
    if threshold_deg <= float(tilt_deg[-1]):
        ax.axvline(threshold_deg, color="0.4", linestyle=":", linewidth=1.2)
        ax.plot([threshold_deg], [limit_mg], marker="o", color="C3")
        ax.annotate(f"{threshold_deg:.3f}° = asin({limit_mg / 1000:g})" if measure == "max-axis"
                    else f"{threshold_deg:.3f}°",
                    xy=(threshold_deg, limit_mg), xytext=(threshold_deg + 0.6, limit_mg * 0.45),
                    arrowprops={"arrowstyle": "->", "color": "0.3"}, fontsize=9)
    ax.set_xlim(0.0, float(tilt_deg[-1]))
    ax.set_ylim(0.0, None)
    ax.set_xlabel("single-axis tilt (deg)")
    ax.set_ylabel("gravity leak (mg)")
    ax.set_title("Gravity leak of a levelled calibration vs. tilt")
    ax.legend(loc="upper left")
    return save_png(fig, path)


def report_markdown(m: dict[str, Any]) -> str:
    """The text of ``small_angle.md`` from the metrics."""
    th = m["threshold_deg"]
    limit = m["limit_mg"]
    measure = m["measure"]
    other_key = next(k for k in m if k.startswith("threshold_deg_"))
    other = m[other_key]
    lines = [
        "# Small-angle analysis of a levelled calibration",
        "",
        "A levelled calibration assumes the sensor rests level, z up, and takes the bias as",
        "`mean − g·e_z`. A sensor tilted by roll φ (about x) and pitch θ (about y) reads",
        "`g·u + b` with `u = [−sin θ, sin φ·cos θ, cos φ·cos θ]`, so gravity leaks into the bias",
        "estimate by `g·(u − e_z)`.",
        "",
        f"`{PNG_NAME}` shows the {_measure_label(measure)} (`{measure}`) in mg over roll × pitch",
        f"(±{m['grid']['range_deg']:g}°, step {m['grid']['step_deg']:g}°) with the {limit:g} mg contour;",
        f"`{PROFILE_PNG_NAME}` (data in `{PROFILE_CSV_NAME}`) shows it against a single-axis tilt.",
        "",
        "## Threshold",
        "",
        "| tilt | threshold (deg) |",
        "|---|---|",
        f"| pitch only | {th['pitch']:.4f} |",
        f"| roll only | {th['roll']:.4f} |",
        f"| equal roll and pitch (per axis) | {th['combined']:.4f} |",
        "",
    ]
    if measure == "max-axis":
        lines += [
            "A single-axis tilt α leaks `g·sin α` into the tangential axis (more than the",
            "`g·(1 − cos α)` of the vertical one), so the leak reaches the limit L at",
            f"`asin(L)`: **asin({limit / 1000:g}) = {m['formula_deg']:.4f}°**. With equal roll and pitch",
            "the x leak is still `g·sin α`, so the per-axis threshold is the same angle.",
            "",
            f"A levelled calibration is therefore only valid to within {limit:g} mg when the sensor",
            f"is level to within **±{th['pitch']:.2f}°** on each axis; beyond that the gravity leak,",
            "not the sensor's bias, dominates the estimate.",
        ]
    else:
        lines += [
            "With the norm measure the leak is `2·g·sin(γ/2)` for a total tilt γ, reached at",
            f"γ = 2·asin(L/2); a single-axis tilt reaches {limit:g} mg at {th['pitch']:.4f}°.",
        ]
    lines += [
        "",
        f"For comparison, the `{other_key.removeprefix('threshold_deg_').replace('_', '-')}` measure "
        f"gives {other['pitch']:.4f}° (single axis) and {other['combined']:.4f}° (equal roll and pitch, "
        "per axis).",
        "",
    ]
    return "\n".join(lines)


def write_report(out: Path, range_deg: float, step_deg: float, limit_mg: float,
                 measure: Measure = "max-axis") -> dict[str, Any]:
    """Compute the analysis and write every output file into ``out``.

    Parameters
    ----------
    out
        Output folder (created).
    range_deg, step_deg
        Grid half-width and spacing, degrees.
    limit_mg
        Tolerated leak, mg.
    measure
        Leak measure.

    Returns
    -------
    dict
        The metrics written to ``small_angle.json``.
    """
    out.mkdir(parents=True, exist_ok=True)
    result = analyse(range_deg, step_deg, limit_mg / 1000.0, measure)
    m = metrics(result, range_deg, step_deg)
    write_bytes_atomic(out / JSON_NAME, (json.dumps(m, indent=2, sort_keys=True) + "\n").encode("utf-8"))
    tilt, leak = profile(range_deg, step_deg, measure)
    write_bytes_atomic(out / PROFILE_CSV_NAME, profile_csv(tilt, leak))
    surface_figure(result, out / PNG_NAME)
    profile_figure(tilt, leak, result.threshold_deg["pitch"], limit_mg, measure, out / PROFILE_PNG_NAME)
    write_bytes_atomic(out / MD_NAME, report_markdown(m).encode("utf-8"))
    return m


