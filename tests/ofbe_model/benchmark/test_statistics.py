"""Benchmark metrics and paired tests against hand computations, and the predictions-table
validation (paired design)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from ofbe_model.benchmark.statistics import (
    T_CRITICAL_DF4,
    check_predictions,
    fold_metrics,
    improvement_pct,
    max_error,
    paired_t,
    rmse,
    signal_errors,
    t_critical,
)


def small_table() -> pd.DataFrame:
    """Two methods, one dataset, two folds of two signals; errors chosen by hand."""
    rows = []
    # (fold, window_id, label, error of "a", error of "b")
    signals = [(0, 0, (1.0, 0.0, 0.0), (3.0, 4.0, 0.0), (0.0, 0.0, 1.0)),
               (0, 1, (0.0, 2.0, 0.0), (0.0, 0.0, 0.0), (0.0, -2.0, 0.0)),
               (1, 2, (0.0, 0.0, 3.0), (1.0, 2.0, 2.0), (0.5, 0.0, 0.0)),
               (1, 3, (1.0, 1.0, 1.0), (0.0, 0.0, -1.0), (0.0, 0.0, 0.0))]
    for fold, wid, y, ea, eb in signals:
        for method, e in (("a", ea), ("b", eb)):
            rows.append({"dataset": "ds", "devices": "d1,d2", "protocol": "p", "method": method, "fold": fold,
                         "window_id": wid, "device": "d1" if wid % 2 else "d2",
                         **{f"y_{k}": y[i] for i, k in enumerate("xyz")},
                         **{f"yhat_{k}": y[i] + e[i] for i, k in enumerate("xyz")},
                         **{f"std_{k}": math.nan for k in "xyz"}})
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- arrays


def test_rmse_is_the_root_mean_squared_vector_norm() -> None:
    y = np.zeros((2, 3))
    yhat = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    assert rmse(y, yhat) == pytest.approx(math.sqrt((25.0 + 0.0) / 2))
    # not the per-axis RMSE, which would be sqrt(25 / 6)
    assert rmse(y, yhat) != pytest.approx(math.sqrt(25.0 / 6))
    assert rmse(yhat, yhat) == 0.0


def test_signal_errors_and_max_error() -> None:
    y = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    yhat = np.array([[1.0, 3.0, 1.0], [-0.5, 0.0, 1.5]])
    np.testing.assert_allclose(signal_errors(y, yhat), [2.0, math.sqrt(0.25 + 2.25)])
    assert max_error(y, yhat) == 2.0
    assert max_error(np.zeros(3), np.array([0.0, -4.0, 1.0])) == 4.0


def test_shape_mismatch_raises() -> None:
    with pytest.raises(ValueError, match="same"):
        rmse(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="at least one"):
        rmse(np.zeros((0, 3)), np.zeros((0, 3)))


def test_improvement_pct() -> None:
    assert improvement_pct(2.0, 1.0) == pytest.approx(50.0)
    assert improvement_pct(1.0, 2.0) == pytest.approx(-100.0)
    assert improvement_pct(0.04, 0.0) == pytest.approx(100.0)
    assert math.isnan(improvement_pct(0.0, 1.0))


def test_paired_t_against_hand_computation() -> None:
    a = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    b = np.array([1.1, 1.9, 2.7, 3.6, 4.4])
    d = a - b  # −0.1, 0.1, 0.3, 0.4, 0.6
    mean = 0.26
    sd = math.sqrt(sum((x - mean) ** 2 for x in d) / 4)
    t_hand = mean / (sd / math.sqrt(5))
    t, p = paired_t(a, b)
    assert t == pytest.approx(t_hand, rel=1e-12)
    assert p == pytest.approx(2 * stats.t.sf(abs(t_hand), 4), rel=1e-9)
    ref = stats.ttest_rel(a, b)
    assert (t, p) == pytest.approx((ref.statistic, ref.pvalue))
    # order: positive when the first sample is larger
    t2, p2 = paired_t(b, a)
    assert t2 == pytest.approx(-t) and p2 == pytest.approx(p)


def test_paired_t_degenerate_cases_without_warnings() -> None:
    a = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert paired_t(a, a.copy()) == (0.0, 1.0)
        t, p = paired_t(a + 1.0, a + 0.5)
        assert t == math.inf and p == 0.0
        t, p = paired_t(a[:1], a[:1] + 1)
        assert math.isnan(t) and math.isnan(p)
    with pytest.raises(ValueError, match="finite"):
        paired_t(np.array([1.0, math.nan]), np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="same length"):
        paired_t(np.ones(3), np.ones(4))


def test_critical_value() -> None:
    assert round(t_critical(4), 3) == 2.776 == T_CRITICAL_DF4
    assert t_critical(4) == pytest.approx(stats.t.ppf(0.975, 4))
    assert t_critical(10_000) == pytest.approx(1.960, abs=1e-3)
    assert t_critical(4, alpha=0.01) == pytest.approx(4.604, abs=1e-3)
    assert math.isnan(t_critical(0))


# ----------------------------------------------------------------------------- the table


def test_fold_metrics_by_hand() -> None:
    fm = fold_metrics(small_table())
    assert list(fm.columns) == ["dataset", "method", "seed", "fold", "rmse", "max_error", "n"]
    assert fm[["method", "fold"]].values.tolist() == [["a", 0], ["a", 1], ["b", 0], ["b", 1]]
    # a, fold 0: norms 5 and 0; fold 1: norms 3 and 1
    np.testing.assert_allclose(fm["rmse"], [math.sqrt(25 / 2), math.sqrt(10 / 2), math.sqrt(5 / 2),
                                            math.sqrt(0.25 / 2)])
    np.testing.assert_allclose(fm["max_error"], [4.0, 2.0, 2.0, 0.5])
    assert fm["n"].tolist() == [2, 2, 2, 2]


def test_check_sorts_and_aligns_methods() -> None:
    table = small_table().sample(frac=1.0, random_state=3)
    df = check_predictions(table)
    assert df[["method", "window_id"]].values.tolist() == [["a", 0], ["a", 1], ["a", 2], ["a", 3],
                                                           ["b", 0], ["b", 1], ["b", 2], ["b", 3]]
    assert df["fold"].dtype == np.int64
    # the input is not modified
    assert table.index.tolist() != list(range(len(table)))


def test_paired_design_violation_names_the_missing_rows() -> None:
    table = small_table()
    table = table[~((table["method"] == "b") & (table["window_id"] == 2))]
    expected = r"paired design.*'b' lacks 1: \(dataset='ds', fold=1, window_id=2\)"
    with pytest.raises(ValueError, match=expected):
        check_predictions(table)
    with pytest.raises(ValueError, match="paired design"):
        fold_metrics(table)


def test_other_violations() -> None:
    table = small_table()
    with pytest.raises(ValueError, match="missing yhat_z"):
        check_predictions(table.drop(columns="yhat_z"))
    with pytest.raises(ValueError, match="duplicated"):
        check_predictions(pd.concat([table, table.iloc[:1]]))
    other = table.copy()
    other.loc[(other["method"] == "b") & (other["window_id"] == 1), "y_y"] += 0.01
    with pytest.raises(ValueError, match="same labels"):
        check_predictions(other)
    other = table.copy()
    other.loc[other["method"] == "a", "std_x"] = 0.1
    with pytest.raises(ValueError, match="some signals or axes but not"):
        check_predictions(other)
    other = table.copy()
    other.loc[0, "yhat_x"] = math.nan
    with pytest.raises(ValueError, match="finite"):
        check_predictions(other)
    other = table.copy()
    other.loc[0, "devices"] = "d1"
    with pytest.raises(ValueError, match="one 'devices' value"):
        check_predictions(other)
    other = table.copy()
    other["fold"] = other["fold"] + 0.5
    with pytest.raises(ValueError, match="integer 'fold'"):
        check_predictions(other)
