"""``ofbe-convergence``: the paper's convergence analysis over a labelled campaign.

For every labelled (recording, device) the running mean of each axis over the stationary
segment is followed until the paper's criterion holds (mean of the last 40 |Δ running
mean| below 5e-6 m/s², :mod:`ofbe_data.labelling.convergence`). The report gives the per-axis
statistics, the histogram with mean ± 1 std shaded, one example running-mean curve with its
label, an Allan-deviation figure per device, and the recommended fewest samples per label,
which the label stage consumes (``reports/convergence/convergence.json``).

The sessions are labelled here with the same code and parameters as ``ofbe-label`` but
without the length floor (``label.min_samples``), since that floor is what the analysis
determines; this is also why the report can be made before the label stage.
"""

from __future__ import annotations

import dataclasses
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data import __version__
from ofbe_data.core.atomic import atomic_directory, write_bytes_atomic
from ofbe_data.core.errors import ConfigError, OfbeError
from ofbe_data.core.figures import new_figure, save_png
from ofbe_data.core.parallel import TaskFailure, map_progress
from ofbe_data.dataset.windows import load_segments
from ofbe_data.io.typedconfig import from_plain
from ofbe_data.labelling.allan import AllanResult, allan_deviation, combine, white_noise_level
from ofbe_data.labelling.convergence import (
    AXES,
    REPORT_FORMAT,
    STATISTICS,
    AxisConvergence,
    axis_statistics,
    recommend_min_samples,
    running_mean,
    step_average,
)
from ofbe_data.labelling.labels import LabelParams, label_session

PAPER_BAND = (4000, 5000)
"""The paper's range of convergence indices on x, samples."""
ALLAN_MAX_SAMPLES = 3000
"""Longest Allan cluster, samples (20 s at 150 Hz); a segment needs three times this."""


@dataclass(frozen=True)
class ConvergenceParams:
    """What the recommendation is based on (``convergence:`` in params.yaml).

    Attributes
    ----------
    axis
        Axis whose statistics give the recommendation (the paper uses x).
    statistic
        One of :data:`ofbe_data.labelling.convergence.STATISTICS`.
    round_to
        The recommendation is rounded up to a multiple of this many samples.
    bins
        Histogram bins.
    """

    axis: str = "x"
    statistic: str = "mean"
    round_to: int = 100
    bins: int = 30


@dataclass
class Analysis:
    """Everything the report is made from.

    Attributes
    ----------
    rows
        One row per analysed (recording, device): identity, n_samples, fs_hz, bias and
        convergence per axis.
    allan
        Per device, the pooled Allan deviation of its recordings.
    allan_recordings
        Per device, how many recordings were pooled (those long enough).
    folders
        Session folder of each (campaign, session).
    rejected
        Rejections of the labeller (reason → count).
    """

    rows: pd.DataFrame
    allan: dict[str, AllanResult]
    allan_recordings: dict[str, int]
    folders: dict[tuple[str, str], Path]
    rejected: dict[str, int] = field(default_factory=dict)


def allan_taus(fs_hz: float) -> np.ndarray:
    """Cluster times of the Allan curves, s: about 10 per decade from one sample to
    :data:`ALLAN_MAX_SAMPLES`, the same for every recording so curves can be pooled."""
    m = np.unique(np.round(np.logspace(0, np.log10(ALLAN_MAX_SAMPLES), 36)).astype(int))
    return m / fs_hz


def _analyse_session(args: tuple[Path, LabelParams]) -> tuple[Path, list[dict[str, Any]],
                                                             list[tuple[str, AllanResult]], list[str], str]:
    folder, params = args
    try:
        labels = label_session(folder, params, keep_segments=True)
    except OfbeError as exc:
        return folder, [], [], [], str(exc)
    rows, allan = [], []
    for r in labels.rows:
        seg = r.pop("_segment")
        rows.append({k: v for k, v in r.items() if not k.startswith("_")})
        if seg.shape[0] >= 3 * ALLAN_MAX_SAMPLES:
            fs = float(np.round(r["fs_hz"]))
            allan.append((r["device"], allan_deviation(seg, fs, allan_taus(fs))))
    return folder, rows, allan, [rj.reason for rj in labels.rejections], ""


def analyse(folders: Sequence[Path], params: LabelParams, jobs: int = 1, progress: bool = True,
            scheduler: str = "processes") -> Analysis:
    """Label sessions without the length floor and gather convergence and Allan data.

    Parameters
    ----------
    folders
        Session folders.
    params
        Labelling parameters (``min_samples`` is ignored).
    jobs
        Worker processes.
    progress
        Show a progress bar.
    scheduler
        Where the sessions are analysed: ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`).

    Returns
    -------
    Analysis

    Raises
    ------
    OfbeError
        A session could not be labelled, or its worker failed (the first such session named,
        with how many more failed).
    """
    params = dataclasses.replace(params, min_samples=2)
    work = [(f, params) for f in folders]
    results = [(folders[r.item_index], [], [], [], f"{folders[r.item_index]}: {r.reason}")
               if isinstance(r, TaskFailure) else r
               for r in map_progress(_analyse_session, work, jobs=jobs, desc="convergence", unit="session",
                                     progress=progress, scheduler=scheduler, on_error="collect")]
    rows: list[dict[str, Any]] = []
    per_device: dict[str, list[AllanResult]] = {}
    folder_of: dict[tuple[str, str], Path] = {}
    rejected: dict[str, int] = {}
    errors = [err for *_, err in results if err]
    if errors:
        more = f" (and {len(errors) - 1} more sessions failed)" if len(errors) > 1 else ""
        raise OfbeError(errors[0] + more)
    for folder, session_rows, allan, reasons, _ in results:
        rows.extend(session_rows)
        for r in session_rows:
            folder_of[(r["campaign"], r["session"])] = folder
        for dev, res in allan:
            per_device.setdefault(dev, []).append(res)
        for reason in reasons:
            rejected[reason] = rejected.get(reason, 0) + 1
    keep = ["campaign", "session", "recording", "device", "kind", "n_samples", "fs_hz", "g_local",
            "raw_file", "raw_sha256", "segment_start_s", "segment_end_s", "bias_x", "bias_y", "bias_z",
            "convergence_x", "convergence_y", "convergence_z"]
    frame = pd.DataFrame(rows, columns=keep)
    frame = frame.sort_values(["campaign", "session", "recording", "device"], kind="stable")
    frame = frame.reset_index(drop=True)
    devices = sorted(per_device)
    return Analysis(frame, {d: combine(per_device[d]) for d in devices},
                    {d: len(per_device[d]) for d in devices}, folder_of, dict(sorted(rejected.items())))


def pick_example(rows: pd.DataFrame, axis: str, target: float) -> int:
    """Index of the row whose convergence index on ``axis`` is closest to ``target``
    (the first such row in identity order)."""
    idx = rows[f"convergence_{axis}"].to_numpy(dtype=np.float64)
    dist = np.where(idx >= 0, np.abs(idx - target), np.inf)
    return int(np.argmin(dist))


# ----------------------------------------------------------------------------- figures


def histogram_figure(rows: pd.DataFrame, stats: dict[str, AxisConvergence], bins: int,
                     recommended: int, path: Path) -> None:
    """Histogram of the convergence index per axis, mean ± 1 std shaded; each panel's title
    says how many recordings never converged (they have no index and are not drawn)."""
    fig, axes = new_figure(1, 3, width_in=10.0, height_in=3.4, sharey=True)
    for ax, name in zip(axes, AXES, strict=True):
        idx = rows[f"convergence_{name}"].to_numpy()
        idx = idx[idx >= 0]
        s = stats[name]
        ax.hist(idx, bins=bins, color="#4c72b0", alpha=0.9, zorder=2, label="recordings")
        if np.isfinite(s.mean):
            ax.axvspan(s.mean - s.std, s.mean + s.std, color="#dd8452", alpha=0.3, zorder=1,
                       label="mean ± 1 std")
            ax.axvline(s.mean, color="#dd8452", lw=2, zorder=3, label="mean")
        ax.axvline(recommended, color="k", ls="--", lw=1, zorder=3, label=f"label length ({recommended})")
        head = (f"{name}: {s.mean:.0f} ± {s.std:.0f} samples (n = {s.n - s.n_not_converged})"
                if np.isfinite(s.mean) else f"{name}: no recording converged")
        ax.set_title(f"{head}\n{s.n_not_converged} of {s.n} recordings never converged (not shown)",
                     fontsize=9)
        ax.set_xlabel("convergence index (samples)")
        ax.set_ylim(0, ax.get_ylim()[1] * 1.35)
    axes[0].set_ylabel("recordings")
    axes[0].legend(loc="upper left", fontsize=8)
    save_png(fig, path)


def example_figure(x: np.ndarray, axis: str, fs_hz: float, label: float, index: int, recommended: int,
                   threshold: float, window: int, title: str, path: Path) -> None:
    """One recording's running mean with its label, and the criterion's statistic."""
    m = running_mean(x)
    avg = step_average(x, window)
    k = np.arange(1, x.shape[0] + 1)
    fig, (top, bottom) = new_figure(2, 1, width_in=6.4, height_in=5.2, sharex=True)
    top.plot(k, m, color="#4c72b0", lw=1.2, label=f"running mean of {axis}")
    top.axhline(label, color="#c44e52", lw=1.2, label=f"segment mean (label) {label:.4f} m/s²")
    top.axvline(index, color="#55a868", lw=1.2, label=f"converged at {index} samples")
    top.axvline(recommended, color="k", ls="--", lw=1, label=f"label length {recommended}")
    spread = 5 * float(np.std(x)) / np.sqrt(500)
    top.set_ylim(label - spread, label + spread)
    top.set_ylabel(f"running mean, {axis} (m/s²)")
    top.set_title(f"{title}: running mean of the {axis} axis")
    top.legend(loc="upper right")
    bottom.semilogy(k, avg, color="#4c72b0", lw=1, label=f"mean of last {window} |Δ running mean|")
    bottom.axhline(threshold, color="#c44e52", lw=1.2, label=f"threshold {threshold:g} m/s²")
    bottom.axvline(index, color="#55a868", lw=1.2)
    bottom.set_xlabel(f"samples (at {fs_hz:.0f} Hz)")
    bottom.set_ylabel("criterion (m/s²)")
    bottom.legend(loc="upper right")
    save_png(fig, path)


def allan_figure(device: str, res: AllanResult, n_recordings: int, recommended: int, fs_hz: float,
                 path: Path) -> None:
    """Allan deviation of one device's recordings (pooled), per axis, in mg."""
    fig, ax = new_figure(width_in=6.4, height_in=4.4)
    g0 = 9.80665
    colours = ("#4c72b0", "#55a868", "#c44e52")
    noise = white_noise_level(res)
    for i, name in enumerate(AXES):
        ax.loglog(res.taus_s, res.adev[:, i] / g0 * 1e3, "o-", ms=3, color=colours[i], label=f"{name}")
        white = noise.density[i] / np.sqrt(res.taus_s) / g0 * 1e3
        ax.loglog(res.taus_s, white, ":", color=colours[i], lw=1,
                  label=f"{name} white noise, {noise.density[i] / g0 * 1e6:.0f} µg/√Hz")
    tau_label = recommended / fs_hz
    ax.axvline(tau_label, color="k", ls="--", lw=1,
               label=f"label length {recommended} samples ({tau_label:.0f} s)")
    ax.set_xlabel("cluster time τ (s)")
    ax.set_ylabel("Allan deviation (mg)")
    ax.set_title(f"{device}: overlapping Allan deviation, {n_recordings} recordings pooled")
    ax.legend(loc="upper right", fontsize=8)
    save_png(fig, path)


# ----------------------------------------------------------------------------- outputs


def _json_bytes(obj: Any) -> bytes:
    return (json.dumps(obj, indent=1, sort_keys=True, allow_nan=False) + "\n").encode()


def _finite(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def report_dict(analysis: Analysis, stats: dict[str, AxisConvergence], params: ConvergenceParams,
                label_params: LabelParams, recommended: int, example: dict[str, Any]) -> dict[str, Any]:
    """The content of ``convergence.json``."""
    rows = analysis.rows
    x = stats["x"]
    allan = {}
    for dev, res in analysis.allan.items():
        noise = white_noise_level(res)
        allan[dev] = {
            "recordings": analysis.allan_recordings[dev],
            "noise_density_ug_per_rthz": {a: round(float(noise.density[i]) / 9.80665 * 1e6, 3)
                                          for i, a in enumerate(AXES)},
            "white_noise_rms_mg": {a: round(float(noise.sigma_sample[i]) / 9.80665 * 1e3, 4)
                                   for i, a in enumerate(AXES)},
            "standard_error_at_label_length_mg": {
                a: round(float(noise.sigma_sample[i]) / np.sqrt(recommended) / 9.80665 * 1e3, 5)
                for i, a in enumerate(AXES)},
        }
    return {
        "format": REPORT_FORMAT,
        "toolkit_version": __version__,
        "criterion": {"window": label_params.convergence_window,
                      "threshold_m_s2": label_params.convergence_threshold},
        "campaigns": sorted(rows["campaign"].unique().tolist()),
        "n_recordings": len(rows),
        "rejected": analysis.rejected,
        "axes": {a: {k: (_finite(v) if isinstance(v, float) else v) for k, v in stats[a].to_dict().items()}
                 for a in AXES},
        "paper_band_x": list(PAPER_BAND),
        "x_mean_within_paper_band": bool(np.isfinite(x.mean) and PAPER_BAND[0] <= x.mean <= PAPER_BAND[1]),
        "recommendation": {"axis": params.axis, "statistic": params.statistic, "round_to": params.round_to,
                           "min_samples": recommended},
        "recommended_label_start": recommended,
        "example": example,
        "allan": allan,
        "recordings": [
            {"campaign": r.campaign, "session": r.session, "recording": r.recording, "device": r.device,
             "n_samples": int(r.n_samples), "convergence_x": int(r.convergence_x),
             "convergence_y": int(r.convergence_y), "convergence_z": int(r.convergence_z)}
            for r in rows.itertuples()],
    }


def report_markdown(doc: dict[str, Any]) -> str:
    """``convergence.md``: the report for a person."""
    ax = doc["axes"]
    x = ax["x"]
    rec = doc["recommendation"]
    band = doc["paper_band_x"]

    def fmt(v: float | None, digits: int = 0) -> str:
        return "–" if v is None else f"{v:.{digits}f}"

    verdict = ("inside" if doc["x_mean_within_paper_band"] else "OUTSIDE")
    lines = [
        "# Convergence of the label (running mean)",
        "",
        f"Campaigns: {', '.join(doc['campaigns'])}; {doc['n_recordings']} labelled (recording, device) "
        "pairs.",
        "",
        f"**On the x axis the running mean converges after {fmt(x['mean'])} ± {fmt(x['std'])} samples "
        f"(mean ± 1 std), {verdict} the paper's {band[0]}–{band[1]} band.** "
        f"The recommended fewest samples per label is **{rec['min_samples']}** "
        f"({rec['statistic']} of axis {rec['axis']}, rounded up to {rec['round_to']}); the label stage "
        "uses it as `label.min_samples` unless params.yaml overrides it.",
        "",
        f"Criterion (paper): the running mean m_k has converged at the first k where the mean of the last "
        f"{doc['criterion']['window']} values of |m_k − m_(k−1)| is below "
        f"{doc['criterion']['threshold_m_s2']:g} m/s².",
        "",
        "| axis | recordings | never converged | mean | std | median | 5 % | 95 % | min | max |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for a in AXES:
        s = ax[a]
        lines.append(f"| {a} | {s['n']} | {s['n_not_converged']} | {fmt(s['mean'])} | {fmt(s['std'])} | "
                     f"{fmt(s['median'])} | {fmt(s['p05'])} | {fmt(s['p95'])} | {fmt(s['min'])} | "
                     f"{fmt(s['max'])} |")
    lines += [
        "",
        "The z axis is noisier (datasheet: 430 against 290 µg/√Hz), so its running mean needs more "
        "samples; the paper's length follows x, and so does the default recommendation "
        "(`convergence.axis`/`convergence.statistic` choose another).",
        "",
        "![histogram](convergence_histogram.png)",
        "",
        "## Example",
        "",
        f"{doc['example']['session']}/{doc['example']['recording']}, {doc['example']['device']}: "
        f"axis {doc['example']['axis']} converges after {doc['example']['index']} samples to "
        f"{doc['example']['label_m_s2']:.5f} m/s² (the mean over its {doc['example']['n_samples']} "
        "stationary samples).",
        "",
        "![example](convergence_example.png)",
        "",
        "## Why about this many samples: Allan deviation",
        "",
        "The label is a mean, so its error from white noise falls as σ/√N (slope −1/2 in the "
        "Allan plots) until slow in-run drift (the flat part, bias instability) takes over. "
        "Past the recommended length the white-noise error of the label is a few hundredths of "
        "a milligravity, well below the turn-on repeatability (milligravities) that the label is meant "
        "to capture, so longer segments add little. Allan deviation by the allantools library "
        "(overlapping ADEV, `oadev`), pooled over each device's recordings.",
        "",
        "| device | recordings | white noise x / y / z (µg/√Hz) | per-sample rms x / y / z (mg) | "
        "σ/√N at the label length x / y / z (mg) |",
        "|---|---|---|---|---|",
    ]
    for dev, a in doc["allan"].items():
        nd, rms, se = (a["noise_density_ug_per_rthz"], a["white_noise_rms_mg"],
                       a["standard_error_at_label_length_mg"])
        lines.append(f"| {dev} | {a['recordings']} | {nd['x']:.0f} / {nd['y']:.0f} / {nd['z']:.0f} | "
                     f"{rms['x']:.2f} / {rms['y']:.2f} / {rms['z']:.2f} | "
                     f"{se['x']:.3f} / {se['y']:.3f} / {se['z']:.3f} |")
    lines += [""] + [f"![Allan deviation, {dev}](allan_{dev}.png)" for dev in doc["allan"]]
    if doc["rejected"]:
        lines += ["", "Rejected by the labeller (not analysed): "
                  + ", ".join(f"{k} {v}" for k, v in doc["rejected"].items()) + "."]
    lines += ["", f"Made by ofbe {doc['toolkit_version']} (`ofbe-convergence`).", ""]
    return "\n".join(lines)


def write_report(analysis: Analysis, out_dir: Path, params: ConvergenceParams, label_params: LabelParams,
                 example_id: str | None = None) -> dict[str, Any]:
    """Write every file of the report into ``out_dir`` (replaced as a whole, atomically).

    Returns
    -------
    dict
        The content of ``convergence.json``.
    """
    rows = analysis.rows
    if rows.empty:
        raise OfbeError("convergence: expected at least one labelled recording, found none "
                        f"(rejected: {analysis.rejected or 'none'})")
    stats = {a: axis_statistics(rows[f"convergence_{a}"].to_numpy()) for a in AXES}
    try:
        recommended = recommend_min_samples(stats[params.axis], params.statistic, params.round_to)
    except ValueError as exc:
        raise OfbeError(f"convergence: {exc}") from exc
    if example_id:
        ident = rows["session"] + "/" + rows["recording"] + "/" + rows["device"]
        hits = np.flatnonzero(ident.to_numpy() == example_id)
        if not hits.size:
            raise OfbeError(f"--example: expected SESSION/RECORDING/DEVICE of an analysed recording, "
                            f"found {example_id!r}")
        i = int(hits[0])
    else:
        i = pick_example(rows, params.axis, stats[params.axis].mean)
    row = rows.iloc[i]
    seg = load_segments(analysis.folders[(row.campaign, row.session)], [row.to_dict()])[0]
    k = AXES.index(params.axis)
    example = {"session": row.session, "recording": row.recording, "device": row.device,
               "axis": params.axis, "index": int(row[f"convergence_{params.axis}"]),
               "n_samples": int(row.n_samples), "label_m_s2": float(seg[:, k].mean()),
               "bias_m_s2": float(row[f"bias_{params.axis}"])}
    doc = report_dict(analysis, stats, params, label_params, recommended, example)
    fs = float(np.round(rows["fs_hz"].median()))
    with atomic_directory(out_dir, replace=True) as tmp:
        histogram_figure(rows, stats, params.bins, recommended, tmp / "convergence_histogram.png")
        example_figure(seg[:, k], params.axis, fs, example["label_m_s2"], example["index"], recommended,
                       label_params.convergence_threshold, label_params.convergence_window,
                       f"{row.session}/{row.recording}, {row.device}", tmp / "convergence_example.png")
        for dev, res in analysis.allan.items():
            allan_figure(dev, res, analysis.allan_recordings[dev], recommended, fs, tmp / f"allan_{dev}.png")
        buf = io.StringIO()
        rows[["campaign", "session", "recording", "device", "n_samples", "convergence_x", "convergence_y",
              "convergence_z"]].to_csv(buf, index=False, lineterminator="\n")
        write_bytes_atomic(tmp / "convergence_indices.csv", buf.getvalue().encode())
        allan_rows = [{"device": dev, "tau_s": f"{tau:.6g}", **{f"adev_{a}_m_s2": f"{res.adev[j, n]:.6e}"
                                                                 for n, a in enumerate(AXES)}}
                      for dev, res in analysis.allan.items() for j, tau in enumerate(res.taus_s)]
        buf = io.StringIO()
        pd.DataFrame(allan_rows).to_csv(buf, index=False, lineterminator="\n")
        write_bytes_atomic(tmp / "allan.csv", buf.getvalue().encode())
        write_bytes_atomic(tmp / "convergence.md", report_markdown(doc).encode())
        write_bytes_atomic(tmp / "convergence.json", _json_bytes(doc))
    return doc


def convergence_params_from(data: dict[str, Any] | None, source: str) -> ConvergenceParams:
    """:class:`ConvergenceParams` from a plain mapping, checked."""
    params: ConvergenceParams = from_plain(data or {}, ConvergenceParams, source, "convergence")
    if params.axis not in AXES:
        raise ConfigError(source, "convergence.axis", "x, y or z", repr(params.axis))
    if params.statistic not in STATISTICS:
        raise ConfigError(source, "convergence.statistic", " / ".join(STATISTICS), repr(params.statistic))
    if params.round_to < 1 or params.bins < 1:
        raise ConfigError(source, "convergence.round_to/bins", "integers ≥ 1",
                          f"{params.round_to}, {params.bins}")
    return params


