"""Benchmark metrics and paired tests (methods.md §Metrics and statistics).

Pure functions on arrays and on the *predictions table*, the one input of the benchmark
report: a pandas DataFrame with one row per (method, test signal) and the columns

- ``dataset`` (str): benchmark dataset, e.g. ``gravity-aligned`` or ``rotated/sparkfun-1``;
- ``devices`` (str): comma-separated device ids of the dataset (one value per dataset);
- ``protocol`` (str), ``method`` (str), ``fold`` (int), ``window_id`` (int), ``device`` (str);
- ``y_x, y_y, y_z``: the label, m/s²; ``yhat_x, yhat_y, yhat_z``: the estimate, m/s²;
- ``std_x, std_y, std_z``: the posterior standard deviation, m/s², NaN when the method has
  none;
- ``seed`` (int, optional, 0 when absent): the training seed of a method trained several
  times (OFBENet); such a method has one row per seed and signal.

The design is paired: every method (and every seed of it) has exactly the same (dataset,
fold, window_id) rows, with the same labels, so per-signal and per-fold values of two methods
can be compared pairwise (:func:`check_predictions` enforces it).

Conventions
-----------
- Error of a signal: ``e_i = ŷ_i − y_i`` (estimate minus label), m/s², per axis.
- RMSE (paper eq. 24): ``sqrt(mean_i ‖e_i‖²)``, with ‖·‖ the Euclidean norm over the three
  axes, so it is the root of the mean *squared vector error*, not a per-axis RMSE.
- Maximum error E_max: the largest ``|e|`` over signals and axes.
- Paired t-tests are two-sided (:func:`scipy.stats.ttest_rel`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

AXES = ("x", "y", "z")
"""Axis suffixes of the vector columns."""

LABEL_COLUMNS = tuple(f"y_{a}" for a in AXES)
ESTIMATE_COLUMNS = tuple(f"yhat_{a}" for a in AXES)
STD_COLUMNS = tuple(f"std_{a}" for a in AXES)
KEY_COLUMNS = ("dataset", "fold", "window_id")
"""The columns that identify a test signal; every method has the same keys."""
REQUIRED_COLUMNS = ("dataset", "devices", "protocol", "method", "fold", "window_id", "device",
                    *LABEL_COLUMNS, *ESTIMATE_COLUMNS, *STD_COLUMNS)
"""Columns of the predictions table."""
SEED_COLUMN = "seed"
"""Optional column: the training seed (0 when absent)."""

T_CRITICAL_DF4 = 2.776
"""Two-sided critical |t| at α = 0.05 with 4 degrees of freedom (5 folds), as in the paper."""

LABEL_ATOL_M_S2 = 1e-9
"""Largest difference between two methods' labels of the same signal, m/s² (they must agree)."""

_MAX_NAMED = 5
"""How many missing keys an error message names before summarising."""


# ----------------------------------------------------------------------------- arrays


def _pair(y: np.ndarray, yhat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both arrays as float64 (N, D) with N ≥ 1, checked to have the same shape."""
    y = np.asarray(y, dtype=np.float64)
    yhat = np.asarray(yhat, dtype=np.float64)
    if y.ndim == 1:
        y = y[None, :]
    if yhat.ndim == 1:
        yhat = yhat[None, :]
    if y.shape != yhat.shape or y.ndim != 2:
        raise ValueError(f"expected labels and estimates of the same (N, 3) shape, found {y.shape} and "
                         f"{yhat.shape}")
    if y.shape[0] == 0:
        raise ValueError("expected at least one signal, found none")
    return y, yhat


def signal_errors(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """Euclidean norm of each signal's error.

    Parameters
    ----------
    y, yhat
        (N, 3) label and estimate, m/s² (a single (3,) vector is one signal).

    Returns
    -------
    numpy.ndarray
        (N,) ``‖ŷ_i − y_i‖``, m/s².
    """
    y, yhat = _pair(y, yhat)
    return np.sqrt(np.sum((yhat - y) ** 2, axis=1))


def rmse(y: np.ndarray, yhat: np.ndarray) -> float:
    """Root mean squared vector error, ``sqrt(mean_i ‖y_i − ŷ_i‖²)`` (paper eq. 24).

    Parameters
    ----------
    y, yhat
        (N, 3) label and estimate, m/s².

    Returns
    -------
    float
        RMSE, m/s².
    """
    y, yhat = _pair(y, yhat)
    return float(np.sqrt(np.mean(np.sum((yhat - y) ** 2, axis=1))))


def max_error(y: np.ndarray, yhat: np.ndarray) -> float:
    """Largest absolute error over signals and axes, ``max_{i,k} |y_ik − ŷ_ik|``.

    Parameters
    ----------
    y, yhat
        (N, 3) label and estimate, m/s².

    Returns
    -------
    float
        E_max, m/s².
    """
    y, yhat = _pair(y, yhat)
    return float(np.max(np.abs(yhat - y)))


def improvement_pct(rmse_baseline: float, rmse_method: float) -> float:
    """Relative RMSE reduction of a method against a baseline, percent.

    ``(rmse_baseline − rmse_method) / rmse_baseline · 100``: positive when the method is
    better, 100 for a perfect method, negative when it is worse.

    Parameters
    ----------
    rmse_baseline, rmse_method
        RMSEs, m/s² (any common unit).

    Returns
    -------
    float
        Improvement, %; NaN when the baseline's RMSE is zero or not finite.
    """
    if not (np.isfinite(rmse_baseline) and np.isfinite(rmse_method)) or rmse_baseline == 0:
        return math.nan
    return float((rmse_baseline - rmse_method) / rmse_baseline * 100.0)


def paired_t(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Two-sided paired t-test of ``mean(a − b) = 0`` (:func:`scipy.stats.ttest_rel`).

    Parameters
    ----------
    a, b
        (n,) paired samples (e.g. the fold RMSEs of a baseline and of a method, m/s²).

    Returns
    -------
    t, p
        The t statistic (positive when ``a`` is larger on average; df = n − 1) and the
        two-sided p-value. Degenerate cases are answered without warnings: identical
        samples give ``(0.0, 1.0)``; a constant non-zero difference gives ``(±inf, 0.0)``
        (both to within 64 ulps of the samples' largest magnitude); fewer than two pairs
        give ``(nan, nan)``.

    Raises
    ------
    ValueError
        The samples differ in shape, are not one-dimensional or are not finite.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"paired_t: expected two 1-D samples of the same length, found shapes {a.shape} "
                         f"and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("paired_t: expected finite samples, found NaN or inf")
    if a.size < 2:
        return math.nan, math.nan
    d = a - b
    # differences equal to within rounding (relative to the samples' size) have no spread
    tol = 64 * np.finfo(np.float64).eps * float(max(np.max(np.abs(a)), np.max(np.abs(b))))
    if float(np.max(d) - np.min(d)) <= tol:
        mean = float(np.mean(d))
        if abs(mean) <= tol:
            return 0.0, 1.0
        return math.copysign(math.inf, mean), 0.0
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        res = stats.ttest_rel(a, b)
    return float(res.statistic), float(res.pvalue)


def t_critical(df: int, alpha: float = 0.05) -> float:
    """Two-sided critical |t| of Student's t distribution.

    Parameters
    ----------
    df
        Degrees of freedom (≥ 1); for the fold-level test, the number of folds − 1.
    alpha
        Significance level of the two-sided test.

    Returns
    -------
    float
        ``t.ppf(1 − α/2, df)`` (2.776 for df = 4, α = 0.05); NaN for df < 1.
    """
    if df < 1:
        return math.nan
    return float(stats.t.ppf(1.0 - alpha / 2.0, df))


# ----------------------------------------------------------------------------- the table


def _describe_keys(keys: Sequence[tuple[object, ...]]) -> str:
    shown = ", ".join(f"(dataset={k[0]!r}, fold={k[1]}, window_id={k[2]})" for k in keys[:_MAX_NAMED])
    more = f" and {len(keys) - _MAX_NAMED} more" if len(keys) > _MAX_NAMED else ""
    return shown + more


def _run_name(method: str, seed: int) -> str:
    """How messages name one method's run: the method, and its seed when not 0."""
    return method if seed == 0 else f"{method} (seed {seed})"


def check_predictions(pred: pd.DataFrame) -> pd.DataFrame:
    """Validate the predictions table and return it in canonical order.

    Checks: the columns exist; labels and estimates are finite; ``fold``, ``window_id`` and
    ``seed`` are integers; no (dataset, method, seed, fold, window_id) appears twice;
    ``devices`` has one value per dataset; every method and seed has the same (dataset, fold,
    window_id) rows (paired design) with the same labels (within :data:`LABEL_ATOL_M_S2`); posterior standard
    deviations are either all NaN or all finite and non-negative per method.

    Parameters
    ----------
    pred
        The predictions table (module docstring).

    Returns
    -------
    pandas.DataFrame
        A copy sorted by (dataset, method, seed, fold, window_id) with a fresh index; ``seed``
        (0 when the input has none), ``fold`` and ``window_id`` as int64. Within a dataset, the
        rows of every method and seed are therefore aligned signal by signal.

    Raises
    ------
    ValueError
        Naming what is wrong (for the paired design: which method lacks which keys).
    """
    missing_cols = [c for c in REQUIRED_COLUMNS if c not in pred.columns]
    if missing_cols:
        raise ValueError(f"predictions: expected columns {', '.join(REQUIRED_COLUMNS)}; missing "
                         f"{', '.join(missing_cols)}")
    if pred.empty:
        raise ValueError("predictions: expected at least one row, found none")
    df = pred.loc[:, list(REQUIRED_COLUMNS)].copy()
    df[SEED_COLUMN] = pred[SEED_COLUMN].to_numpy() if SEED_COLUMN in pred.columns else 0
    for col in ("fold", "window_id", SEED_COLUMN):
        values = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=np.float64)
        if not np.all(np.isfinite(values)) or np.any(values != np.round(values)):
            raise ValueError(f"predictions: expected integer {col!r}, found {df[col].dtype} values that "
                             "are not")
        df[col] = values.astype(np.int64)
    for col in ("dataset", "devices", "protocol", "method", "device"):
        df[col] = df[col].astype(str)
    vec = df[[*LABEL_COLUMNS, *ESTIMATE_COLUMNS]].to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(vec)):
        bad = df.loc[~np.isfinite(vec).all(axis=1), "method"].unique().tolist()
        raise ValueError(f"predictions: expected finite labels and estimates; NaN or inf in methods {bad}")
    ident = ["dataset", "method", SEED_COLUMN, "fold", "window_id"]
    dup = df.duplicated(ident, keep=False)
    if dup.any():
        first = df.loc[dup, ident].iloc[0].tolist()
        raise ValueError(f"predictions: expected one row per (dataset, method, seed, fold, window_id), found "
                         f"{int(dup.sum())} duplicated rows, e.g. {first}")
    n_devices = df.groupby("dataset")["devices"].nunique()
    if (n_devices > 1).any():
        raise ValueError(f"predictions: expected one 'devices' value per dataset; datasets "
                         f"{sorted(n_devices[n_devices > 1].index)} have several")
    df = df.sort_values(ident, kind="stable").reset_index(drop=True)

    keys_by_method = {_run_name(m, seed): set(map(tuple, g[list(KEY_COLUMNS)].itertuples(index=False)))
                      for (m, seed), g in df.groupby(["method", SEED_COLUMN], sort=True)}
    every = set().union(*keys_by_method.values())
    problems = []
    for method, keys in keys_by_method.items():
        lacking = sorted(every - keys)
        if lacking:
            problems.append(f"method {method!r} lacks {len(lacking)}: {_describe_keys(lacking)}")
    if problems:
        raise ValueError("predictions: expected every method on the same (dataset, fold, window_id) rows "
                         "(paired design); " + "; ".join(problems))

    methods = list(keys_by_method)
    labels = {_run_name(m, seed): g[list(LABEL_COLUMNS)].to_numpy(dtype=np.float64)
              for (m, seed), g in df.groupby(["method", SEED_COLUMN], sort=True)}
    for m in methods[1:]:
        worst = float(np.max(np.abs(labels[m] - labels[methods[0]])))
        if worst > LABEL_ATOL_M_S2:
            raise ValueError(f"predictions: expected the same labels for every method (paired design); "
                             f"{m!r} and {methods[0]!r} differ by up to {worst:.3g} m/s²")
    for m, g in df.groupby("method", sort=True):
        s = g[list(STD_COLUMNS)].to_numpy(dtype=np.float64)
        finite = np.isfinite(s)
        if finite.any() and not finite.all():
            raise ValueError(f"predictions: method {m!r} has a posterior std on some signals or axes but not "
                             f"on others ({int((~finite).sum())} of {s.size} values are NaN or inf)")
        if finite.all() and np.any(s < 0):
            raise ValueError(f"predictions: method {m!r} has negative posterior std")
    return df


def errors_of(pred: pd.DataFrame) -> np.ndarray:
    """Per-signal error vectors ``ŷ − y`` of a (checked) predictions table.

    Returns
    -------
    numpy.ndarray
        (N, 3) m/s², in the table's row order.
    """
    return (pred[list(ESTIMATE_COLUMNS)].to_numpy(dtype=np.float64)
            - pred[list(LABEL_COLUMNS)].to_numpy(dtype=np.float64))


def fold_metrics(pred: pd.DataFrame) -> pd.DataFrame:
    """RMSE and maximum error per (dataset, method, seed, fold).

    Parameters
    ----------
    pred
        The predictions table (validated with :func:`check_predictions`).

    Returns
    -------
    pandas.DataFrame
        Columns ``dataset, method, seed, fold, rmse, max_error, n`` (m/s², m/s², signals),
        one row per (dataset, method, seed, fold), sorted by those keys.
    """
    df = check_predictions(pred)
    rows = []
    for (dataset, method, seed, fold), g in df.groupby(["dataset", "method", SEED_COLUMN, "fold"], sort=True):
        y = g[list(LABEL_COLUMNS)].to_numpy(dtype=np.float64)
        yhat = g[list(ESTIMATE_COLUMNS)].to_numpy(dtype=np.float64)
        rows.append({"dataset": dataset, "method": method, "seed": int(seed), "fold": int(fold),
                     "rmse": rmse(y, yhat), "max_error": max_error(y, yhat), "n": len(g)})
    return pd.DataFrame(rows, columns=["dataset", "method", "seed", "fold", "rmse", "max_error", "n"])
