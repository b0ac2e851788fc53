"""Shared figure style and atomic PNG output for every report.

Every figure of the toolkit goes through :func:`new_figure` and :func:`save_png`, so that
the reports share one readable style (sizes fit a journal column at 300 dpi, labelled axes
with units, legends without frames) and no half-written PNG is ever left behind.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # no display is needed or assumed

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ofbe_data.core.atomic import write_bytes_atomic  # noqa: E402

DPI = 200
"""Resolution of the written PNGs, dots per inch."""

STYLE: dict[str, Any] = {
    "font.size": 10,
    "axes.titlesize": 11,
    "axes.labelsize": 10,
    "legend.fontsize": 9,
    "legend.frameon": False,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "savefig.dpi": DPI,
    "figure.constrained_layout.use": True,
    "svg.hashsalt": "ofbe",
}
"""Matplotlib rc settings used by every figure."""


def new_figure(nrows: int = 1, ncols: int = 1, width_in: float = 6.4, height_in: float = 4.0,
               **kwargs: Any) -> tuple[Figure, Any]:
    """A figure and its axes in the toolkit's style.

    Parameters
    ----------
    nrows, ncols
        Subplot grid.
    width_in, height_in
        Figure size, inches.
    **kwargs
        Passed to :func:`matplotlib.pyplot.subplots`.

    Returns
    -------
    fig, axes
        As :func:`matplotlib.pyplot.subplots` returns them.
    """
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(nrows, ncols, figsize=(width_in, height_in), **kwargs)
    fig.set_layout_engine("constrained")
    return fig, axes


def save_png(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` as a PNG atomically and close it.

    The PNG carries no creation time or software version, so the same figure gives the
    same bytes.

    Parameters
    ----------
    fig
        The figure.
    path
        Target ``.png``; its folder is created.

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    with plt.rc_context(STYLE):
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())
    return path
