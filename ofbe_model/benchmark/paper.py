"""The paper's published Table 3 beside ours (the ``paper`` block of ``benchmark.json``).

Levin & Klein report, per dataset, the mean RMSE over five folds of three methods: the
Least Squares and the Mathematical Model baselines and OFBENet (the Mathematical Model only
on the rotated devices). :data:`PAPER_TABLE3` holds those numbers, keyed by our protocol and
benchmark dataset name (the pipeline's campaigns ``gravity-aligned`` and ``rotated``).
Their improvement percentages are derived from them as the paper defines them,
(RMSE_baseline − RMSE_method) / RMSE_baseline · 100, and the paper reports OFBENet's
improvement over each baseline as significant in its paired t-tests
(:data:`PAPER_SIGNIFICANT`).

Our counterparts: the paper's Least Squares is the first baseline of the benchmark, its
Mathematical Model the second (``benchmark.baselines`` in params.yaml: the variants that
behave as the paper's did, docs/benchmark.md), OFBENet is ``ofbenet``. Methods beyond the
paper (:data:`BEYOND_THE_PAPER`) are listed with no paper value, with their oracle ratio.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

PAPER_METHODS = ("Least Squares", "Mathematical Model", "OFBENet")
"""The paper's Table 3 methods, in its order."""
PAPER_BASELINES = PAPER_METHODS[:2]
"""The paper's baselines; ours are ``benchmark.baselines`` in the same order."""
PAPER_TABLE3: dict[tuple[str, str], dict[str, Any]] = {
    ("paper-gravity", "gravity-aligned"): {
        "name": "gravity-aligned, 4 SparkFun boards",
        "rmse": {"Least Squares": 0.1767, "OFBENet": 0.0839}},
    ("paper-rotated", "rotated/sparkfun-1"): {
        "name": "rotated, SparkFun 1",
        "rmse": {"Least Squares": 0.1711, "Mathematical Model": 0.2088, "OFBENet": 0.0392}},
    ("paper-rotated", "rotated/sparkfun-2"): {
        "name": "rotated, SparkFun 2",
        "rmse": {"Least Squares": 0.3180, "Mathematical Model": 0.1869, "OFBENet": 0.0407}},
}
"""Mean RMSE (m/s²) of the paper's Table 3, by (protocol, benchmark dataset)."""
PAPER_SIGNIFICANT = True
"""The paper's verdict on OFBENet against each of its baselines: a significant improvement."""
OFBENET = "ofbenet"
BEYOND_THE_PAPER = ("gravity-prior-direction", "oracle")
"""Our methods shown beside the paper's rows (no paper value)."""


def _r(v: float | None, digits: int = 6) -> float | None:
    if v is None or not math.isfinite(v):
        return None
    return float(f"{float(v):.{digits}g}") + 0.0


def _improvement(base: float | None, method: float | None) -> float | None:
    if base is None or method is None or base == 0:
        return None
    return (base - method) / base * 100.0


def paper_comparison(protocol: str, datasets: dict[str, Any], baselines: Sequence[str]) -> dict[str, Any]:
    """The ``paper`` block of ``benchmark.json``: the paper's Table 3 beside ours.

    Parameters
    ----------
    protocol
        The benchmark's protocol.
    datasets
        ``summarise``'s ``datasets`` (per dataset: ``t_critical_fold`` and ``methods``).
    baselines
        The baselines present, in order: the paper's Least Squares, then its Mathematical
        Model.

    Returns
    -------
    dict
        ``{dataset: {"paper_dataset", "rows": [{"paper_method", "method", "paper_rmse",
        "rmse_mean", "ratio", "oracle_ratio", "improvement_pct": {paper baseline: {"paper",
        "ours"}}, "significant": {paper baseline: {"paper", "ours", "t"}}}]}}`` for the
        datasets the paper reports under this protocol (empty when none). ``ratio`` is ours
        over the paper's; improvement and significance are given for OFBENet only;
        ``significant.ours`` is the fold-level paired t-test against our counterpart of that
        baseline beyond the two-sided critical value, with ``t`` positive when OFBENet's
        error is lower. Null where either side has no value.
    """
    ours_of = dict(zip(PAPER_BASELINES, baselines, strict=False))
    ours_of[PAPER_METHODS[2]] = OFBENET
    out: dict[str, Any] = {}
    for name, ds in datasets.items():
        paper = PAPER_TABLE3.get((protocol, name))
        if paper is None:
            continue
        methods = ds["methods"]
        crit = ds["t_critical_fold"]["value"]
        prmse = paper["rmse"]
        rows = []
        for pm in PAPER_METHODS:
            m = ours_of.get(pm)
            if m is None or m not in methods:
                continue
            v = methods[m]
            p = prmse.get(pm)
            row: dict[str, Any] = {
                "paper_method": pm, "method": m, "paper_rmse": p, "rmse_mean": v["rmse_mean"],
                "ratio": _r(v["rmse_mean"] / p) if p and v["rmse_mean"] is not None else None,
                "oracle_ratio": v["oracle_ratio"], "improvement_pct": {}, "significant": {}}
            if pm == PAPER_METHODS[2]:
                for pb in PAPER_BASELINES:
                    b = ours_of.get(pb)
                    has_paper = pb in prmse
                    ours_imp = v["improvement_pct"].get(b) if b else None
                    t = v["t_test"].get(b, {}).get("fold", {}).get("t") if b else None
                    row["improvement_pct"][pb] = {
                        "paper": _r(_improvement(prmse.get(pb), p), 4) if has_paper else None,
                        "ours": ours_imp}
                    row["significant"][pb] = {
                        "paper": PAPER_SIGNIFICANT if has_paper else None,
                        "ours": (bool(abs(t) > crit) if t is not None and crit is not None else None),
                        "t": t}
            rows.append(row)
        for m in BEYOND_THE_PAPER:
            if m in methods:
                rows.append({"paper_method": None, "method": m, "paper_rmse": None,
                             "rmse_mean": methods[m]["rmse_mean"], "ratio": None,
                             "oracle_ratio": methods[m]["oracle_ratio"], "improvement_pct": {},
                             "significant": {}})
        out[name] = {"paper_dataset": paper["name"], "rows": rows}
    return out


def _num(v: float | None, fmt: str) -> str:
    return "–" if v is None else format(v, fmt)


def _verdict(v: bool | None, t: float | None = None) -> str:
    if v is None:
        return "–"
    word = "yes" if v else "no"
    return word if t is None else f"{word} (t = {t:.1f})"


def paper_table_rows(dataset: str, block: dict[str, Any], first: bool = True) -> list[str]:
    """Markdown rows of one dataset's comparison (see :func:`paper_markdown` for the columns)."""
    lines = []
    for i, r in enumerate(block["rows"]):
        imp = r["improvement_pct"]
        sig = r["significant"]
        cells = [f"{block['paper_dataset']} (`{dataset}`)" if i == 0 and first else "",
                 r["paper_method"] or "(beyond the paper)", f"`{r['method']}`",
                 _num(r["paper_rmse"], ".4f"), _num(r["rmse_mean"], ".4f"), _num(r["ratio"], ".2f")]
        for pb in PAPER_BASELINES:
            if pb in imp:
                cells.append(f"{_num(imp[pb]['paper'], '.1f')} / {_num(imp[pb]['ours'], '.1f')}")
            else:
                cells.append("")
        for pb in PAPER_BASELINES:
            if pb in sig:
                cells.append(f"{_verdict(sig[pb]['paper'])} / {_verdict(sig[pb]['ours'], sig[pb]['t'])}")
            else:
                cells.append("")
        cells.append(_num(r["oracle_ratio"], ".2f"))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


PAPER_HEADER = ("| Dataset (paper) | Paper's method | Ours | Paper RMSE (m/s²) | Our RMSE (m/s²) "
                "| Ours / paper | Improvement % vs Least Squares (paper / ours) "
                "| vs Mathematical Model (paper / ours) | Significant vs Least Squares (paper / ours) "
                "| vs Mathematical Model (paper / ours) | ×oracle |")
PAPER_LEGEND = (
    "Paper: Levin & Klein's Table 3 (mean RMSE over 5 folds, m/s²); its improvement % derived from it "
    "as (RMSE_baseline − RMSE_OFBENet) / RMSE_baseline · 100; its significance: OFBENet's improvement "
    "over each baseline is reported significant. Ours: this benchmark; the paper's Least Squares and "
    "Mathematical Model are our first and second baselines (the variants that behave as the paper's did, "
    "docs/benchmark.md); significance: fold-level paired two-sided t-test beyond the critical |t| (2.776 "
    "at df = 4), t positive when OFBENet's error is lower. Ours / paper: our mean RMSE over the paper's. "
    "×oracle: our mean RMSE over the oracle's. Rows beyond the paper have no paper value. –: not reported "
    "or not applicable.")


def paper_markdown(paper: dict[str, Any]) -> str:
    """The comparison as a Markdown table with its legend, or "" when no dataset has a paper row.

    Columns: Dataset (paper) | Paper's method | Ours | Paper RMSE | Our RMSE | Ours / paper |
    improvement % against each paper baseline (paper / ours) | significance against each (paper /
    ours) | ×oracle.
    """
    if not paper:
        return ""
    lines = [PAPER_HEADER, "|---|---|---|" + "---:|" * 8]
    for name, block in paper.items():
        lines += paper_table_rows(name, block)
    return "\n".join([*lines, "", PAPER_LEGEND]) + "\n"
