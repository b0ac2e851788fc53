"""The benchmark report: the paper's Table 3, its figures and its t-tests (paper §4).

Made from the predictions table (:mod:`ofbe_model.benchmark.statistics`: one row per method and test
signal, paired design). :func:`write_report` writes into one folder (replaced as a whole,
atomically; products.md §Reports, ``reports/benchmark/<protocol>/``):

- ``benchmark.json``: DVC metrics, format ``ofbe-benchmark/1`` (:func:`summarise`); sorted
  keys, floats rounded to :data:`SIGNIFICANT_DIGITS` significant digits, NaN and ±inf as
  ``null``, so the same predictions always give the same bytes;
- ``benchmark.md``: Table 3 (:func:`table3_markdown`), the figures, the paper's published
  Table 3 beside ours (:mod:`ofbe_model.benchmark.paper`), the fold- and
  signal-level t-test tables per baseline, the calibration of posterior stds, notes;
- ``errors.csv``: per-signal error vectors ``ŷ − y`` and their norms (DVC plots);
- ``fold_metrics.csv``: RMSE and E_max per (dataset, method, fold) (DVC plots);
- ``rmse.png``, ``max_error.png``, ``t_<baseline>.png`` (one per baseline present).

Conventions of the statistics
-----------------------------
- ``rmse_std`` is the *sample* standard deviation (ddof = 1) of the fold RMSEs, as a spread
  over folds; it is null with a single fold.
- A method trained with several seeds (OFBENet, ``train.seeds``) has one predictions row per
  seed and signal. Its fold RMSEs, maximum errors and per-signal error norms are averaged
  over seeds before anything else (the t-tests included): the performance of one model,
  not of an ensemble. ``rmse_seeds`` holds each seed's mean RMSE and ``rmse_seed_std`` their
  sample standard deviation, the spread that retraining alone causes.
- ``improvement_pct[b] = (rmse_mean[b] − rmse_mean[m]) / rmse_mean[b] · 100`` on the
  across-fold mean RMSEs: positive when the method beats baseline ``b``.
- ``t_test[b]`` compares baseline ``b`` with the method, ``paired_t(baseline, method)``:
  positive t when the method's error is lower. Fold level: the fold RMSEs (df = n_folds − 1;
  critical |t| = 2.776 at df = 4, α = 0.05). Signal level: the per-signal error norms
  ``‖ŷ_i − y_i‖`` of the two methods on the same signals (df = n_signals − 1).
- A method is never compared with itself: a baseline has no entry for itself.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.core.atomic import atomic_directory, write_bytes_atomic
from ofbe_model.benchmark.figures import max_error_figure, rmse_figure, t_figure
from ofbe_model.benchmark.ordering import all_methods, ordered_methods
from ofbe_model.benchmark.paper import paper_comparison, paper_markdown
from ofbe_model.benchmark.statistics import (
    AXES,
    STD_COLUMNS,
    T_CRITICAL_DF4,
    check_predictions,
    errors_of,
    fold_metrics,
    improvement_pct,
    paired_t,
    t_critical,
)

REPORT_FORMAT = "ofbe-benchmark/1"
"""Value of ``format`` in ``benchmark.json``."""
DEFAULT_BASELINES = ("ls-trf", "won2009")
"""The paper's baselines."""
SIGNIFICANT_DIGITS = 6
"""Significant digits of the floats in ``benchmark.json``."""
ALPHA = 0.05
"""Significance level of the t-tests."""
"""Bar charts use a log y axis when their positive values span more than this many decades."""
CSV_FLOAT_FORMAT = "%.9g"
"""Float format of the CSV files."""

# ----------------------------------------------------------------------------- numbers


def _round(v: float | None, digits: int = SIGNIFICANT_DIGITS) -> float | None:
    """``v`` to ``digits`` significant digits; None for None, NaN and ±inf."""
    if v is None or not math.isfinite(v):
        return None
    return float(f"{float(v):.{digits}g}") + 0.0  # + 0.0 turns −0.0 into 0.0


def _round_list(values: Iterable[float]) -> list[float | None]:
    return [_round(float(v)) for v in values]


def _sample_std(values: np.ndarray) -> float:
    """Sample standard deviation (ddof = 1); NaN for fewer than two values."""
    return float(np.std(values, ddof=1)) if values.size > 1 else math.nan


# ----------------------------------------------------------------------------- summary


def _method_stats(errors: np.ndarray, std: np.ndarray) -> tuple[float | None, float | None,
                                                                 dict[str, float | None] | None]:
    """Mean posterior std, pooled 1σ coverage and per-axis coverage of one method's signals.

    Parameters
    ----------
    errors, std
        (N, 3) error vectors and posterior stds, m/s² (std all NaN when the method has none).
    """
    if not np.all(np.isfinite(std)):
        return None, None, None
    inside = np.abs(errors) <= std
    return (_round(float(np.mean(std))), _round(float(np.mean(inside))),
            {a: _round(float(np.mean(inside[:, k]))) for k, a in enumerate(AXES)})


def _dataset_summary(df: pd.DataFrame, folds: pd.DataFrame, baselines: Sequence[str],
                     oracle: str | None) -> dict[str, Any]:
    """The ``datasets[<name>]`` entry of ``benchmark.json`` (see :func:`summarise`).

    Parameters
    ----------
    df
        The checked predictions of one dataset (canonical order, so methods are aligned).
    folds
        Its rows of :func:`ofbe_model.benchmark.statistics.fold_metrics`.
    baselines
        Baselines present in the table.
    oracle
        The oracle's method name, or None when there is none.
    """
    methods = sorted(df["method"].unique())
    fold_ids = sorted(int(f) for f in df["fold"].unique())
    per: dict[str, dict[str, np.ndarray]] = {}
    for m in methods:
        rows = df[df["method"] == m]  # sorted by seed, fold, window_id: aligned per seed
        fm = folds[folds["method"] == m].sort_values(["seed", "fold"])
        n_seeds = int(rows["seed"].nunique())
        rmse_by_seed = fm["rmse"].to_numpy(dtype=np.float64).reshape(n_seeds, len(fold_ids))
        err = errors_of(rows)
        norm = np.sqrt(np.sum(err**2, axis=1)).reshape(n_seeds, -1)
        # a method trained with several seeds enters the tests with its fold RMSEs and error
        # norms averaged over seeds: the expected single model, not an ensemble
        per[m] = {"rmse": rmse_by_seed.mean(axis=0),
                  "max": fm["max_error"].to_numpy(dtype=np.float64).reshape(n_seeds, -1).mean(axis=0),
                  "err": err, "norm": norm.mean(axis=0), "seed_rmse": rmse_by_seed.mean(axis=1),
                  "seeds": np.sort(rows["seed"].unique()),
                  "std": rows[list(STD_COLUMNS)].to_numpy(dtype=np.float64)}
    means = {m: float(np.mean(per[m]["rmse"])) for m in methods}
    out: dict[str, Any] = {}
    for m in methods:
        p = per[m]
        others = [b for b in baselines if b != m]
        mean_std, coverage, coverage_axes = _method_stats(p["err"], p["std"])
        t_test = {}
        for b in others:
            tf, pf = paired_t(per[b]["rmse"], p["rmse"])
            ts, ps = paired_t(per[b]["norm"], p["norm"])
            t_test[b] = {"fold": {"t": _round(tf), "p": _round(pf)},
                         "signal": {"t": _round(ts), "p": _round(ps)}}
        out[m] = {
            "rmse_folds": _round_list(p["rmse"]),
            "rmse_mean": _round(means[m]),
            "rmse_std": _round(_sample_std(p["rmse"])),
            "seeds": [int(v) for v in p["seeds"]],
            "rmse_seeds": _round_list(p["seed_rmse"]),
            "rmse_seed_std": _round(_sample_std(p["seed_rmse"])),
            "max_error_folds": _round_list(p["max"]),
            "max_error_mean": _round(float(np.mean(p["max"]))),
            "improvement_pct": {b: _round(improvement_pct(means[b], means[m])) for b in others},
            "t_test": t_test,
            "oracle_ratio": (_round(means[m] / means[oracle]) if oracle is not None and means[oracle] > 0
                             else None),
            "mean_std_m_s2": mean_std,
            "coverage_1sigma": coverage,
            "coverage_1sigma_axes": coverage_axes,
        }
    devices = [d.strip() for d in str(df["devices"].iloc[0]).split(",") if d.strip()]
    df_fold = len(fold_ids) - 1
    return {
        "devices": devices,
        "n_signals": int(per[methods[0]]["norm"].size),
        "n_folds": len(fold_ids),
        "folds": fold_ids,
        "t_critical_fold": {"alpha": ALPHA, "df": df_fold, "value": _round(t_critical(df_fold, ALPHA), 4)},
        "methods": out,
    }


def summarise(pred: pd.DataFrame, baselines: Sequence[str] = DEFAULT_BASELINES,
              oracle: str | None = "oracle") -> dict[str, Any]:
    """The content of ``benchmark.json``.

    Parameters
    ----------
    pred
        The predictions table (:mod:`ofbe_model.benchmark.statistics`), of a single protocol.
    baselines
        Methods every other method is compared with, in order of importance (the first one
        present is Table 3's reference). Those absent from the table are skipped and listed
        under ``baselines_absent``.
    oracle
        Name of the oracle method (simulated data); ``oracle_ratio`` is null when it is
        absent or None.

    Returns
    -------
    dict
        ``{"format", "protocol", "baselines", "baselines_absent", "oracle", "datasets":
        {dataset: {"devices", "n_signals", "n_folds", "folds", "t_critical_fold", "methods":
        {method: {"rmse_folds", "rmse_mean", "rmse_std", "seeds", "rmse_seeds", "rmse_seed_std",
        "max_error_folds", "max_error_mean",
        "improvement_pct": {baseline: %}, "t_test": {baseline: {"fold": {"t", "p"},
        "signal": {"t", "p"}}}, "oracle_ratio", "mean_std_m_s2", "coverage_1sigma",
        "coverage_1sigma_axes"}}}}, "paper": {dataset: the paper's Table 3 beside ours}}``
        (:func:`ofbe_model.benchmark.paper.paper_comparison`; empty when the paper reports
        none of the datasets under this protocol). Lengths and errors in m/s²; folds ascending; floats
        rounded to :data:`SIGNIFICANT_DIGITS` significant digits; NaN and ±inf as None.
        ``rmse_std`` is the sample std (ddof = 1) over folds; the conventions of the tests
        are in the module docstring. A method with several training seeds (OFBENet) has its
        fold RMSEs, maximum errors and per-signal error norms averaged over seeds;
        ``rmse_seeds`` is the mean RMSE of each seed and ``rmse_seed_std`` their sample std
        (null with one seed).

    Raises
    ------
    ValueError
        The table is invalid (:func:`ofbe_model.benchmark.statistics.check_predictions`) or mixes
        protocols.
    """
    df = check_predictions(pred)
    protocols = sorted(df["protocol"].unique())
    if len(protocols) != 1:
        raise ValueError(f"predictions: expected a single protocol, found {protocols}")
    methods = set(df["method"].unique())
    wanted = list(dict.fromkeys(baselines))
    present = [b for b in wanted if b in methods]
    absent = [b for b in wanted if b not in methods]
    the_oracle = oracle if oracle is not None and oracle in methods else None
    folds = fold_metrics(df)
    datasets = {ds: _dataset_summary(g, folds[folds["dataset"] == ds], present, the_oracle)
                for ds, g in df.groupby("dataset", sort=True)}
    return {"format": REPORT_FORMAT, "protocol": protocols[0], "baselines": present,
            "baselines_absent": absent, "oracle": the_oracle, "datasets": datasets,
            "paper": paper_comparison(protocols[0], datasets, present)}




# ----------------------------------------------------------------------------- Markdown


def _fmt_value(v: float | None, sig: int = 4) -> str:
    """A magnitude in m/s² with ``sig`` significant digits, plain decimals when readable."""
    if v is None:
        return "–"
    if v == 0:
        return "0"
    exponent = math.floor(math.log10(abs(v)))
    if -4 <= exponent < 5:
        return f"{v:.{max(0, sig - 1 - exponent)}f}"
    return f"{v:.{sig - 1}e}"


def _fmt_fixed(v: float | None, digits: int) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _fmt_t(v: float | None, critical: float | None) -> str:
    if v is None:
        return "–"
    star = "*" if critical is not None and math.isfinite(critical) and abs(v) > critical else ""
    return f"{v:.2f}{star}"


def _fmt_p(v: float | None) -> str:
    if v is None:
        return "–"
    return f"{v:.3g}" if v >= 1e-3 else f"{v:.2e}"


def _devices_text(devices: Sequence[str]) -> str:
    if len(devices) <= 4:
        return ", ".join(devices)
    return f"{len(devices)} devices ({devices[0]} … {devices[-1]})"


def _best_methods(ds: dict[str, Any], oracle: str | None) -> set[str]:
    """Methods with the lowest mean RMSE (as printed) of a dataset, the oracle excluded."""
    means = {m: v["rmse_mean"] for m, v in ds["methods"].items()
             if m != oracle and v["rmse_mean"] is not None}
    if not means:
        return set()
    best = _fmt_value(min(means.values()))
    return {m for m, v in means.items() if _fmt_value(v) == best}


def table3_markdown(summary: dict[str, Any], method_order: Sequence[str] | None = None) -> str:
    """The paper's Table 3 as a Markdown table with a legend.

    Columns: Dataset | Sensors | Method | Mean RMSE (m/s²) | STD (m/s²) | Improvement %
    (vs the first baseline present) | one "vs <baseline> (%)" column per further baseline |
    t (fold) vs the first baseline | ×oracle. One block of rows per dataset (its name and
    sensors on the block's first row); the lowest non-oracle mean RMSE of each dataset in bold.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    method_order
        Display order of the methods (see :func:`ordered_methods`).

    Returns
    -------
    str
        Markdown, ending with a newline.
    """
    baselines: list[str] = list(summary["baselines"])
    oracle = summary.get("oracle")
    first = baselines[0] if baselines else None
    header = ["Dataset", "Sensors", "Method", "Mean RMSE (m/s²)", "STD (m/s²)",
              f"Improvement % (vs {first})" if first else "Improvement %"]
    header += [f"vs {b} (%)" for b in baselines[1:]]
    header += [f"t (fold) vs {first}" if first else "t (fold)", "×oracle"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * 3 + "---:|" * (len(header) - 3)]
    dfs: set[int] = set()
    seeded: set[str] = set()
    for name, ds in summary["datasets"].items():
        crit = ds["t_critical_fold"]["value"]
        dfs.add(int(ds["t_critical_fold"]["df"]))
        best = _best_methods(ds, oracle)
        for i, m in enumerate(ordered_methods(ds["methods"], baselines, oracle, method_order)):
            v = ds["methods"][m]
            rmse_text = _fmt_value(v["rmse_mean"])
            if m in best:
                rmse_text = f"**{rmse_text}**"
            if len(v.get("seeds", [])) > 1:
                rmse_text += f" ± {_fmt_value(v['rmse_seed_std'], 2)} ({len(v['seeds'])} seeds)"
                seeded.add(m)
            cells = [name if i == 0 else "", _devices_text(ds["devices"]) if i == 0 else "", m, rmse_text,
                     _fmt_value(v["rmse_std"])]
            cells += [_fmt_fixed(v["improvement_pct"].get(b), 1) for b in baselines] or ["–"]
            t = v["t_test"].get(first, {}).get("fold", {}).get("t") if first else None
            cells += [_fmt_t(t, crit), _fmt_fixed(v["oracle_ratio"], 2)]
            lines.append("| " + " | ".join(cells) + " |")
    crit_text = f"critical |t| = {T_CRITICAL_DF4} (df = 4, α = {ALPHA}, two-sided)"
    other_dfs = sorted(d for d in dfs if d != 4)
    if other_dfs:
        crit_text += "; here also " + ", ".join(f"{t_critical(d, ALPHA):.3f} (df = {d})" for d in other_dfs)
    lines += [
        "",
        "Mean RMSE: mean over the test folds of the fold RMSE, sqrt(mean over signals of ‖ŷ − y‖²) "
        "(paper eq. 24); STD: sample standard deviation (ddof = 1) of the fold RMSEs. "
        + (f"Improvement %: (RMSE_{first} − RMSE_method) / RMSE_{first} · 100 on the mean RMSEs, positive "
           f"when the method is better; \"vs <baseline>\" gives the same against the other baselines. "
           f"t (fold): paired two-sided t-test of the {first} fold RMSEs against the method's, positive when "
           f"the method's error is lower; * marks |t| above the {crit_text}. "
           if first else "No baseline is present, so there is no improvement or t-test. ")
        + ("×oracle: mean RMSE over the oracle's (the posterior mean under the true device prior, the lowest "
           "achievable on simulated data). " if oracle else "×oracle: no oracle in this benchmark. ")
        + "Bold: the lowest mean RMSE of the dataset, oracle excluded. –: not applicable.",
    ]
    if seeded:
        lines += ["", f"{', '.join(sorted(seeded))}: trained with several seeds; mean RMSE ± the sample "
                  "standard deviation over seeds of each seed's mean RMSE, the spread that retraining alone "
                  "causes (a difference smaller than about twice it is not a real one). Its STD, improvement "
                  "and t use the fold RMSEs averaged over seeds."]
    if summary.get("baselines_absent"):
        lines += ["", "Baselines not in the predictions (skipped): "
                  + ", ".join(summary["baselines_absent"]) + "."]
    return "\n".join(lines) + "\n"


def t_test_markdown(summary: dict[str, Any], baseline: str, method_order: Sequence[str] | None = None) -> str:
    """Fold- and signal-level paired t-tests of every method against ``baseline``.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    baseline
        A baseline present in ``summary["baselines"]``.
    method_order
        Display order of the methods.

    Returns
    -------
    str
        A Markdown table: Dataset | Method | t, p (fold, df) | t, p (signal, df).
    """
    lines = ["| Dataset | Method | t (fold) | p (fold) | df (fold) | t (signal) | p (signal) | df (signal) |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    oracle = summary.get("oracle")
    for name, ds in summary["datasets"].items():
        crit_fold = ds["t_critical_fold"]["value"]
        crit_signal = t_critical(ds["n_signals"] - 1, ALPHA)
        for m in ordered_methods(ds["methods"], summary["baselines"], oracle, method_order):
            if m == baseline:
                continue
            tt = ds["methods"][m]["t_test"][baseline]
            lines.append(f"| {name} | {m} | {_fmt_t(tt['fold']['t'], crit_fold)} | "
                         f"{_fmt_p(tt['fold']['p'])} | "
                         f"{ds['n_folds'] - 1} | {_fmt_t(tt['signal']['t'], crit_signal)} | "
                         f"{_fmt_p(tt['signal']['p'])} | {ds['n_signals'] - 1} |")
    return "\n".join(lines) + "\n"


def _calibration_markdown(summary: dict[str, Any], method_order: Sequence[str] | None) -> str:
    rows = []
    for name, ds in summary["datasets"].items():
        for m in ordered_methods(ds["methods"], summary["baselines"], summary.get("oracle"), method_order):
            v = ds["methods"][m]
            if v["mean_std_m_s2"] is None:
                continue
            ax = v["coverage_1sigma_axes"]
            rows.append(f"| {name} | {m} | {_fmt_value(v['mean_std_m_s2'])} | {_fmt_value(v['rmse_mean'])} | "
                        f"{v['coverage_1sigma'] * 100:.1f} | "
                        + " / ".join(f"{ax[a] * 100:.1f}" for a in AXES) + " |")
    if not rows:
        return ""
    return "\n".join(["| Dataset | Method | mean posterior std (m/s²) | mean RMSE (m/s²) | 1σ coverage (%) | "
                      "x / y / z (%) |", "|---|---|---:|---:|---:|---:|", *rows]) + "\n"


def report_markdown(summary: dict[str, Any], title: str, method_order: Sequence[str] | None = None) -> str:
    """``benchmark.md``: Table 3, the figures, the t-test tables and notes.

    Parameters
    ----------
    summary
        The output of :func:`summarise`.
    title
        First heading.
    method_order
        Display order of the methods.
    """
    n_signals = sum(ds["n_signals"] for ds in summary["datasets"].values())
    lines = [
        f"# {title}",
        "",
        f"Protocol `{summary['protocol']}`: {len(summary['datasets'])} datasets, {n_signals} test signals, "
        f"{len(all_methods(summary))} methods. Errors are estimate − label, in m/s².",
        "",
        "## Table 3",
        "",
        table3_markdown(summary, method_order),
        "![mean RMSE per method and dataset](rmse.png)",
        "",
        "![maximum error per method and dataset](max_error.png)",
        "",
    ]
    paper = paper_markdown(summary.get("paper") or {})
    if paper:
        lines += ["## Against the paper's Table 3", "", paper]
    for b in summary["baselines"]:
        lines += [
            f"## Paired t-tests against {b}",
            "",
            f"Positive t: the method's error is lower than {b}'s. Fold level: the fold RMSEs; signal level: "
            "the per-signal error norms ‖ŷ − y‖ on the same signals. * marks |t| above the two-sided "
            f"critical value at α = {ALPHA} for that df (fold level, 5 folds: {T_CRITICAL_DF4}).",
            "",
            t_test_markdown(summary, b, method_order),
            f"![t-statistics against {b}](t_{b}.png)",
            "",
        ]
    calibration = _calibration_markdown(summary, method_order)
    if calibration:
        lines += ["## Posterior standard deviations", "",
                  "For the methods that give one: the mean predicted std over signals and axes, and the "
                  "fraction of axis errors within ±1 std (68.3 % for a calibrated Gaussian posterior).", "",
                  calibration]
    lines += [
        "## Notes",
        "",
        "- RMSE is the root of the mean squared *vector* error (paper eq. 24); E_max is the largest absolute "
        "error over the test signals and axes of a fold, averaged over folds in the figure and JSON.",
        "- STD is the sample standard deviation (ddof = 1) of the fold RMSEs.",
        "- The signal-level test treats the signals as independent pairs; signals of one power cycle share a "
        "bias, so its p-values are optimistic. The fold-level test (df = n_folds − 1) is the paper's.",
        "- Numbers in benchmark.json carry 6 significant digits; errors.csv and fold_metrics.csv carry the "
        "per-signal and per-fold values.",
    ]
    if summary.get("baselines_absent"):
        lines.append("- Baselines requested but absent from the predictions: "
                     + ", ".join(summary["baselines_absent"]) + ".")
    if summary.get("oracle") is None:
        lines.append("- No oracle in the predictions, so no ×oracle ratio.")
    lines.append("")
    return "\n".join(lines)




# ----------------------------------------------------------------------------- files


def _json_bytes(obj: Any) -> bytes:
    return (json.dumps(obj, indent=1, sort_keys=True, allow_nan=False) + "\n").encode()


def _csv_bytes(frame: pd.DataFrame) -> bytes:
    buf = io.StringIO()
    frame.to_csv(buf, index=False, lineterminator="\n", float_format=CSV_FLOAT_FORMAT)
    return buf.getvalue().encode()


def errors_table(pred: pd.DataFrame) -> pd.DataFrame:
    """Per-signal errors, the content of ``errors.csv``.

    Parameters
    ----------
    pred
        The predictions table.

    Returns
    -------
    pandas.DataFrame
        Columns ``dataset, protocol, method, seed, fold, window_id, device, err_x, err_y,
        err_z, err_norm`` (errors ŷ − y and their Euclidean norm, m/s²), sorted by (dataset,
        method, seed, fold, window_id).
    """
    df = check_predictions(pred)
    err = errors_of(df)
    out = df[["dataset", "protocol", "method", "seed", "fold", "window_id", "device"]].copy()
    for k, a in enumerate(AXES):
        out[f"err_{a}"] = err[:, k]
    out["err_norm"] = np.sqrt(np.sum(err**2, axis=1))
    return out


def write_report(out_dir: str | Path, pred: pd.DataFrame, summary: dict[str, Any], title: str,
                 method_order: Sequence[str] | None = None) -> None:
    """Write the benchmark report into ``out_dir`` (replaced as a whole, atomically).

    Files: ``benchmark.json``, ``benchmark.md``, ``errors.csv``, ``fold_metrics.csv``,
    ``rmse.png``, ``max_error.png`` and ``t_<baseline>.png`` per baseline present (module
    docstring). The same inputs give byte-identical files.

    Parameters
    ----------
    out_dir
        Report folder.
    pred
        The predictions table.
    summary
        ``summarise(pred, ...)``.
    title
        Heading of ``benchmark.md``.
    method_order
        Display order of the methods in the tables and figures.

    Raises
    ------
    ValueError
        The table is invalid, or ``summary`` is not of these predictions (other datasets or
        methods).
    """
    df = check_predictions(pred)
    datasets = sorted(df["dataset"].unique())
    if sorted(summary["datasets"]) != datasets:
        raise ValueError(f"write_report: the summary's datasets {sorted(summary['datasets'])} are not the "
                         f"predictions' {datasets}")
    methods = sorted(df["method"].unique())
    for name, ds in summary["datasets"].items():
        if sorted(ds["methods"]) != methods:
            raise ValueError(f"write_report: the summary's methods of {name!r} {sorted(ds['methods'])} "
                             f"are not the predictions' {methods}")
    with atomic_directory(out_dir, replace=True) as tmp:
        write_bytes_atomic(tmp / "benchmark.json", _json_bytes(summary))
        write_bytes_atomic(tmp / "benchmark.md", report_markdown(summary, title, method_order).encode())
        write_bytes_atomic(tmp / "errors.csv", _csv_bytes(errors_table(df)))
        write_bytes_atomic(tmp / "fold_metrics.csv", _csv_bytes(fold_metrics(df)))
        rmse_figure(summary, tmp / "rmse.png", method_order)
        max_error_figure(summary, tmp / "max_error.png", method_order)
        for b in summary["baselines"]:
            t_figure(summary, tmp / f"t_{b}.png", b, method_order)
