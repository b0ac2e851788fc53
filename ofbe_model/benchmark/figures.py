"""The benchmark's figures: mean RMSE and maximum error per method and dataset, and the fold-level
t-statistics against a baseline.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from ofbe_data.core.figures import new_figure, save_png
from ofbe_model.benchmark.ordering import all_methods

# ----------------------------------------------------------------------------- figures

LOG_SPAN_DECADES = 2.0
_COLOURS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3", "#8c8c8c",
            "#ccb974", "#64b5cd")
_ORACLE_COLOUR = "#b0b0b0"



def _span_decades(values: Iterable[float | None]) -> float:
    """Decades spanned by the positive finite values (0 when fewer than two)."""
    v = np.array([x for x in values if x is not None and math.isfinite(x) and x > 0], dtype=np.float64)
    return float(np.log10(v.max() / v.min())) if v.size > 1 else 0.0


def _colours(summary: dict[str, Any], method_order: Sequence[str] | None) -> dict[str, str]:
    """One colour per method, the same in every figure of a report (the oracle grey)."""
    oracle = summary.get("oracle")
    others = [m for m in all_methods(summary, method_order) if m != oracle]
    colours = {m: _COLOURS[i % len(_COLOURS)] for i, m in enumerate(others)}
    if oracle is not None:
        colours[oracle] = _ORACLE_COLOUR
    return colours


def _figure_width(n_datasets: int, n_methods: int) -> float:
    return float(np.clip(1.5 + 0.28 * n_datasets * max(n_methods, 1), 6.4, 16.0))


def _grouped_bars(ax: Axes, summary: dict[str, Any], methods: Sequence[str], colours: dict[str, str],
                  value: Any, yerr: Any = None) -> None:
    """Bars of ``value(ds, method)`` grouped by dataset, one colour per method.

    ``yerr(ds, method)`` gives (lower, upper) whisker lengths or None.
    """
    names = list(summary["datasets"])
    x = np.arange(len(names), dtype=np.float64)
    width = 0.8 / max(len(methods), 1)
    oracle = summary.get("oracle")
    for i, m in enumerate(methods):
        heights, lows, highs = [], [], []
        for n in names:
            ds = summary["datasets"][n]
            v = value(ds, m) if m in ds["methods"] else None
            heights.append(np.nan if v is None else v)
            e = yerr(ds, m) if yerr is not None and m in ds["methods"] else None
            lows.append(0.0 if e is None else e[0])
            highs.append(0.0 if e is None else e[1])
        pos = x - 0.4 + width * (i + 0.5)
        ax.bar(pos, heights, width, color=colours[m], label=m, zorder=2,
               hatch="//" if m == oracle else None, edgecolor="white" if m != oracle else "#606060",
               linewidth=0.5,
               yerr=np.array([lows, highs]) if yerr is not None else None,
               error_kw={"ecolor": "#333333", "elinewidth": 0.8, "capsize": 2})
    ax.set_xticks(x)
    tilt = len(names) > 3
    ax.set_xticklabels(names, rotation=20 if tilt else 0, ha="right" if tilt else "center")
    ax.set_xlabel("dataset")


def _legend(ax: Axes, n: int) -> None:
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), ncols=1 if n <= 12 else 2)


def rmse_figure(summary: dict[str, Any], path: str | Path, method_order: Sequence[str] | None = None) -> Path:
    """Grouped bars of mean RMSE ± 1 std (over folds) per method and dataset.

    The y axis is logarithmic when the mean RMSEs span more than :data:`LOG_SPAN_DECADES`
    decades (the axis label says so); on a log axis the lower whisker is clipped to keep it
    positive.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    path
        Target PNG.
    method_order
        Display order of the methods.

    Returns
    -------
    Path
        The written file.
    """
    methods = all_methods(summary, method_order)
    means = [v["rmse_mean"] for ds in summary["datasets"].values() for v in ds["methods"].values()]
    log = _span_decades(means) > LOG_SPAN_DECADES and all(m is not None and m > 0 for m in means)
    fig, ax = new_figure(width_in=_figure_width(len(summary["datasets"]), len(methods)), height_in=4.2)

    def err(ds: dict[str, Any], m: str) -> tuple[float, float]:
        v = ds["methods"][m]
        s = v["rmse_std"] or 0.0
        mean = v["rmse_mean"] or 0.0
        return (min(s, 0.9 * mean) if log else s), s

    _grouped_bars(ax, summary, methods, _colours(summary, method_order),
                  lambda ds, m: ds["methods"][m]["rmse_mean"], err)
    if log:
        ax.set_yscale("log")
    ax.set_ylabel("mean RMSE over folds (m/s²" + (", log scale)" if log else ")"))
    ax.set_title(f"Mean RMSE ± 1 std over folds\nprotocol {summary['protocol']}")
    _legend(ax, len(methods))
    return save_png(fig, path)


def max_error_figure(summary: dict[str, Any], path: str | Path,
                     method_order: Sequence[str] | None = None) -> Path:
    """Grouped bars of the maximum error E_max per method and dataset.

    Bar: mean over folds of the fold's E_max; whiskers: the smallest and largest fold E_max.
    Log y axis under the same rule as :func:`rmse_figure`.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    path
        Target PNG.
    method_order
        Display order of the methods.

    Returns
    -------
    Path
        The written file.
    """
    methods = all_methods(summary, method_order)
    values = [x for ds in summary["datasets"].values() for v in ds["methods"].values()
              for x in [v["max_error_mean"], *v["max_error_folds"]]]
    log = _span_decades(values) > LOG_SPAN_DECADES and all(x is not None and x > 0 for x in values)
    fig, ax = new_figure(width_in=_figure_width(len(summary["datasets"]), len(methods)), height_in=4.2)

    def err(ds: dict[str, Any], m: str) -> tuple[float, float]:
        v = ds["methods"][m]
        folds = [f for f in v["max_error_folds"] if f is not None]
        mean = v["max_error_mean"]
        if mean is None or not folds:
            return 0.0, 0.0
        return max(mean - min(folds), 0.0), max(max(folds) - mean, 0.0)

    _grouped_bars(ax, summary, methods, _colours(summary, method_order),
                  lambda ds, m: ds["methods"][m]["max_error_mean"], err)
    if log:
        ax.set_yscale("log")
    ax.set_ylabel("max |ŷ − y| of a fold (m/s²" + (", log scale)" if log else ")"))
    ax.set_title(f"Maximum error over signals and axes per fold\n"
                 f"bar: mean over folds, whiskers: min–max; protocol {summary['protocol']}")
    _legend(ax, len(methods))
    return save_png(fig, path)


def t_figure(summary: dict[str, Any], path: str | Path, baseline: str,
             method_order: Sequence[str] | None = None) -> Path:
    """Fold-level paired t-statistic of every method against ``baseline``, per dataset.

    Positive t: the method's fold RMSEs are lower than the baseline's. Horizontal lines mark
    ± the two-sided critical value at α = 0.05 for df = n_folds − 1 (2.776 for 5 folds). The
    y axis is symmetric-logarithmic (linear within ± the critical value) when some |t| of any
    baseline exceeds 50 (so the figures of all baselines share one scale), and the axis label
    says so. Infinite or undefined t are not drawn.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    path
        Target PNG.
    baseline
        A baseline present in ``summary["baselines"]``.
    method_order
        Display order of the methods.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    ValueError
        ``baseline`` is not a baseline of the summary.
    """
    if baseline not in summary["baselines"]:
        raise ValueError(f"t_figure: expected one of the baselines {summary['baselines']}, "
                         f"found {baseline!r}")
    methods = [m for m in all_methods(summary, method_order) if m != baseline]
    fig, ax = new_figure(width_in=max(_figure_width(len(summary["datasets"]), len(methods)), 8.0),
                         height_in=4.6)

    def t_of(ds: dict[str, Any], m: str) -> float | None:
        return ds["methods"][m]["t_test"][baseline]["fold"]["t"]

    _grouped_bars(ax, summary, methods, _colours(summary, method_order), t_of)
    names = list(summary["datasets"])
    crits = [summary["datasets"][n]["t_critical_fold"] for n in names]
    if len({c["df"] for c in crits}) == 1 and crits[0]["value"] is not None:
        c = crits[0]
        ax.axhline(c["value"], color="k", ls="--", lw=1, zorder=3,
                   label=f"±{c['value']:.3f}: critical |t| (df = {c['df']}, α = {c['alpha']})")
        ax.axhline(-c["value"], color="k", ls="--", lw=1, zorder=3)
    else:
        for i, c in enumerate(crits):
            if c["value"] is None:
                continue
            ax.hlines([c["value"], -c["value"]], i - 0.45, i + 0.45, colors="k", linestyles="--", lw=1,
                      zorder=3, label="± critical |t| of the dataset (α = 0.05)" if i == 0 else None)
    ax.axhline(0.0, color="#333333", lw=0.6, zorder=3)
    # one scale for the t figures of every baseline, so that they can be compared side by side
    ts = [abs(t) for n in names for b in summary["baselines"]
          for m, v in summary["datasets"][n]["methods"].items()
          if m != b and (t := v["t_test"][b]["fold"]["t"]) is not None]
    symlog = bool(ts) and max(ts) > 50
    if symlog:
        ax.set_yscale("symlog", linthresh=max(c["value"] or 1.0 for c in crits))
    ax.set_ylabel(f"t (fold RMSEs), {baseline} − method" + (" (symlog scale)" if symlog else ""))
    # over the figure, not the axes: with few datasets the axes are narrower than the title
    fig.suptitle(f"Paired t-test of the fold RMSEs against {baseline}\n"
                 f"positive: lower error than {baseline}; protocol {summary['protocol']}")
    _legend(ax, len(methods) + 1)
    return save_png(fig, path)
