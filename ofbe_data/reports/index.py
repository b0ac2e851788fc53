"""``reports/index.md``: one page that links every table and figure of a pipeline run.

The page is made from what the DVC pipeline left on disk, nothing is recomputed except the
label fidelity (labels against the simulator's truth, :func:`ofbe_data.dataset.fidelity.label_fidelity`):

1. what was run (profile, campaigns, toolkit version);
2. the paper's published Table 3 beside ours (the protocols' "Against the paper's Table 3"
   sections joined in one table), then the paper's Table 3 per benchmark protocol, copied from
   ``reports/benchmark/<protocol>/benchmark.md``, with its figures and files;
3. the convergence headline (``reports/convergence/convergence.json``) and figures;
4. the small-angle thresholds (``reports/small_angle/small_angle.json``) and figures;
5. label fidelity per simulated campaign (``processed/labels/<campaign>`` against ``raw/<campaign>/_truth``);
6. the datasets (``processed/datasets/<campaign>/datapackage.json``) with their cards;
7. OFBENet training (``models/cv/<dataset>/<protocol>/training.json``);
8. stage times, when a timings file is given.

Every link is relative to ``reports/`` (the page lives there) and only points at files that
exist; a missing input gives a sentence instead. The page carries no dates, so the same
inputs give the same bytes.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import OfbeError
from ofbe_data.dataset.fidelity import AXES, TruthError, label_fidelity, truth_dir_of
from ofbe_data.labelling.store import read_labels
from ofbe_data.reports.defaults import TIMINGS_FORMAT

PROG = "ofbe-index"

_IMAGE_LINE = re.compile(r"^\s*!\[[^\]]*\]\([^)]*\)\s*$")
_LINK = re.compile(r"(!?\[[^\]]*\])\(([^)\s]+)\)")


class IndexInputError(OfbeError):
    """An input of the index exists but does not hold what it should."""


# ----------------------------------------------------------------------------- helpers


class _Page:
    """Paths of a project tree and links relative to its ``reports/`` folder."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.reports = root / "reports"

    def rel(self, path: Path) -> str:
        """``path`` relative to ``reports/``, with forward slashes, URL-quoted."""
        return quote(os.path.relpath(path, self.reports).replace(os.sep, "/"))

    def shown(self, path: Path) -> str:
        """``path`` relative to the project root, for prose."""
        return os.path.relpath(path, self.root).replace(os.sep, "/")

    def link(self, path: Path, text: str | None = None) -> str:
        """A Markdown link to ``path``, or the path in backticks marked missing."""
        if not path.is_file():
            return f"`{self.shown(path)}` (missing)"
        return f"[{text or path.name}]({self.rel(path)})"

    def image(self, path: Path, alt: str) -> str | None:
        """A Markdown image of ``path``, or None when the file does not exist."""
        return f"![{alt}]({self.rel(path)})" if path.is_file() else None


def _load_json(path: Path, page: _Page) -> Any:
    """The JSON document at ``path``, or None when there is no such file."""
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise IndexInputError(f"{page.shown(path)}: expected a JSON document, found {exc}") from None


def _layout_error(path: Path, page: _Page, what: str, exc: Exception) -> IndexInputError:
    return IndexInputError(f"{page.shown(path)}: expected {what}, found a missing or malformed field "
                           f"({type(exc).__name__}: {exc})")


def _fmt(v: float | None, digits: int) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _range(values: Sequence[float]) -> str:
    lo, hi = min(values), max(values)
    return f"{lo:g}" if lo == hi else f"{lo:g}–{hi:g}"


def markdown_section(text: str, heading: str) -> str | None:
    """The body of the level-2 section ``## heading`` of a Markdown text, or None.

    The body runs from the line after the heading to the next level-1 or level-2 heading;
    leading and trailing blank lines are dropped.
    """
    lines = text.splitlines()
    try:
        start = lines.index(f"## {heading}") + 1
    except ValueError:
        return None
    end = len(lines)
    for i in range(start, len(lines)):
        if lines[i].startswith("# ") or lines[i].startswith("## "):
            end = i
            break
    return "\n".join(lines[start:end]).strip("\n")


def _intro(text: str) -> str | None:
    """The paragraph between a Markdown text's title and its first section, if any."""
    lines = text.splitlines()
    body = []
    for line in lines[1:] if lines and lines[0].startswith("# ") else lines:
        if line.startswith("#"):
            break
        body.append(line)
    out = "\n".join(body).strip("\n")
    return out or None


def _rebase_links(text: str, prefix: str) -> str:
    """Prefix the relative link targets of ``text`` with ``prefix`` (absolute URLs, anchors kept)."""

    def fix(m: re.Match[str]) -> str:
        target = m.group(2)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE) or target.startswith(("#", "/")):
            return m.group(0)
        return f"{m.group(1)}({prefix}{target})"

    return _LINK.sub(fix, text)


# ----------------------------------------------------------------------------- sections


def _intro_section(campaigns: Sequence[str], protocols: Sequence[str], profile: str | None) -> list[str]:
    run = f"profile `{profile}`" if profile else "no profile named"
    return [
        "# ofbe: index of the reports",
        "",
        f"This page indexes the outputs of the ofbe DVC pipeline ({run}) over the campaigns "
        f"{', '.join(f'`{c}`' for c in campaigns) or '(none)'} and the benchmark protocols "
        f"{', '.join(f'`{p}`' for p in protocols) or '(none)'}, made with ofbe {__version__}. "
        "It reproduces the paper's Table 3 per protocol, the convergence and small-angle analyses, "
        "the labels' fidelity against the simulator's truth, the datasets and the OFBENet training; "
        "every link is relative to this folder (`reports/`).",
        "",
    ]


PAPER_SECTION = "Against the paper's Table 3"
"""Section of ``benchmark.md`` with the paper's published Table 3 beside ours."""


def _paper_section(page: _Page, protocols: Sequence[str]) -> list[str]:
    """One table of the paper's published Table 3 beside ours, joined from the protocols'
    ``benchmark.md`` sections (the rows of each; header and legend of the first); none when no
    protocol has one."""
    header: list[str] = []
    rows: list[str] = []
    legend: list[str] = []
    for protocol in protocols:
        md_path = page.reports / "benchmark" / protocol / "benchmark.md"
        if not md_path.is_file():
            continue
        body = markdown_section(md_path.read_text(encoding="utf-8"), PAPER_SECTION)
        if not body:
            continue
        table = [ln for ln in body.splitlines() if ln.startswith("|")]
        if len(table) < 3:
            continue
        if not header:
            header = table[:2]
            legend = [ln for ln in body.splitlines() if ln.strip() and not ln.startswith("|")]
        rows += table[2:]
    if not rows:
        return []
    return [f"### {PAPER_SECTION}", "",
            "Levin & Klein's published Table 3 (their paper-gravity and paper-rotated protocols) beside this "
            "run's numbers under the same protocols.", "", *header, *rows, "", *legend, ""]


def _benchmark_section(page: _Page, protocols: Sequence[str]) -> list[str]:
    lines = ["## Benchmark (the paper's Table 3)", ""]
    if not protocols:
        lines += ["No benchmark protocol was asked for.", ""]
    lines += _paper_section(page, protocols)
    for protocol in protocols:
        folder = page.reports / "benchmark" / protocol
        lines += [f"### {protocol}", ""]
        if not folder.is_dir():
            lines += [f"Protocol `{protocol}` was not run (no `{page.shown(folder)}`).", ""]
            continue
        md_path = folder / "benchmark.md"
        prefix = f"{page.rel(folder)}/"
        if md_path.is_file():
            text = md_path.read_text(encoding="utf-8")
            intro = _intro(text)
            if intro:
                lines += [_rebase_links(intro, prefix), ""]
            table = markdown_section(text, "Table 3")
            if table is None:
                lines += [f"`{page.shown(md_path)}` has no Table 3 section.", ""]
            else:
                kept = [ln for ln in table.splitlines() if not _IMAGE_LINE.match(ln)]
                lines += [_rebase_links("\n".join(kept).strip("\n"), prefix), ""]
        else:
            lines += [f"No `{page.shown(md_path)}`: the table is not available.", ""]
        figures = [("rmse.png", "mean RMSE per method and dataset"),
                   ("max_error.png", "maximum error per method and dataset")]
        figures += [(p.name, f"t-statistics against {p.stem[2:]}") for p in sorted(folder.glob("t_*.png"))]
        images = [page.image(folder / name, alt) for name, alt in figures]
        lines += [ln for img in images if img for ln in (img, "")]
        missing = [name for (name, _), img in zip(figures, images, strict=True) if img is None]
        if missing:
            lines += [f"Figures not found: {', '.join(missing)}.", ""]
        files = ", ".join(page.link(folder / name)
                          for name in ("benchmark.md", "benchmark.json", "errors.csv", "fold_metrics.csv"))
        lines += [f"Files: {files}.", ""]
    return lines


def _convergence_section(page: _Page) -> list[str]:
    folder = page.reports / "convergence"
    path = folder / "convergence.json"
    lines = ["## Convergence", ""]
    doc = _load_json(path, page)
    if doc is None:
        return lines + [f"The convergence analysis was not run (no `{page.shown(path)}`).", ""]
    try:
        x = doc["axes"]["x"]
        band = doc["paper_band_x"]
        rec = doc["recommendation"]
        n = int(x["n"]) - int(x.get("n_not_converged", 0))
        verdict = "inside" if doc["x_mean_within_paper_band"] else "OUTSIDE"
        campaigns = ", ".join(f"`{c}`" for c in doc.get("campaigns", []))
        headline = (
            f"**On the x axis the running mean converges after {_fmt(x['mean'], 0)} ± {_fmt(x['std'], 0)} "
            f"samples (mean ± 1 std over {n} recordings), {verdict} the paper's {band[0]}–{band[1]} band; "
            f"the recommended label length is {int(rec['min_samples'])} samples** "
            f"({rec['statistic']} of axis {rec['axis']}, rounded up to {rec['round_to']}). "
            f"Campaigns analysed: {campaigns or '(none listed)'}."
        )
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise _layout_error(path, page, "an ofbe-convergence/1 report", exc) from None
    lines += [headline, ""]
    for name, alt in (("convergence_histogram.png", "histogram of the convergence index per axis"),
                      ("convergence_example.png", "running mean of one recording with its label")):
        img = page.image(folder / name, alt)
        lines += [img if img else f"Figure `{name}` not found.", ""]
    allan = sorted(folder.glob("allan_*.png"))
    if allan:
        lines += ["Allan deviation per device: "
                  + ", ".join(page.link(p, p.stem[len("allan_"):]) for p in allan) + ".", ""]
    else:
        lines += ["No Allan deviation figures.", ""]
    lines += [f"Full report: {page.link(folder / 'convergence.md')}.", ""]
    return lines


def _small_angle_section(page: _Page) -> list[str]:
    folder = page.reports / "small_angle"
    path = folder / "small_angle.json"
    lines = ["## Small-angle analysis", ""]
    doc = _load_json(path, page)
    if doc is None:
        return lines + [f"The small-angle analysis was not run (no `{page.shown(path)}`).", ""]
    try:
        th = doc["threshold_deg"]
        limit = float(doc["limit_mg"])
        measure = doc.get("measure", "max-axis")
        rows = [("pitch only", th["pitch"]), ("roll only", th["roll"]),
                ("equal roll and pitch", th["combined"])]
        body = [
            f"A levelled calibration (bias = mean − g·e_z) stays within {limit:g} mg of the bias "
            f"(measure `{measure}`) while the sensor is tilted by less than:",
            "",
            "| tilt | threshold (deg) |",
            "|---|---:|",
            *(f"| {name} | {_fmt(None if v is None else float(v), 3)} |" for name, v in rows),
            "",
        ]
        if "formula_deg" in doc:
            body += [f"Closed form: {doc.get('formula', 'asin(limit)')} = {float(doc['formula_deg']):.3f}°.",
                     ""]
    except (KeyError, TypeError, ValueError) as exc:
        raise _layout_error(path, page, "an ofbe-small-angle/1 report", exc) from None
    lines += body
    for name, alt in (("small_angle.png", "gravity leak over roll and pitch"),
                      ("small_angle_profile.png", "gravity leak against a single-axis tilt")):
        img = page.image(folder / name, alt)
        lines += [img if img else f"Figure `{name}` not found.", ""]
    lines += [f"Full report: {page.link(folder / 'small_angle.md')}.", ""]
    return lines


def _fidelity_table(fid: dict[str, Any]) -> list[str]:
    rows = [("apparent bias (label), RMS", "bias_rms_mg"), ("apparent bias (label), max", "bias_max_mg")]
    if "reference_rms_mg" in fid:
        rows += [("of it, the reference's own bias and scale, RMS", "reference_rms_mg"),
                 ("the rest (the labeller's own error), RMS", "bias_own_rms_mg")]
    if "bias_sensor_frame_rms_mg" in fid:
        rows += [("apparent bias in the sensor's own axes, RMS", "bias_sensor_frame_rms_mg")]
    if "offset_rms_mg" in fid:
        rows += [("zero-g offset, RMS", "offset_rms_mg"), ("zero-g offset, max", "offset_max_mg")]
    out = ["| error | x (mg) | y (mg) | z (mg) |", "|---|---:|---:|---:|"]
    for name, key in rows:
        out.append(f"| {name} | " + " | ".join(f"{float(fid[key][a]):.4f}" for a in AXES) + " |")
    if "reference_rms_mg" in fid:
        out += ["", "A reference-based label takes gravity's direction from the reference's mean reading, "
                "so the reference's own bias and scale errors (the truth's) tilt it: the second row is that "
                "share, computed from the truth alone, the third what is left. No labelling from one window "
                "per orientation removes the reference's share (docs/labelling.md, \"Label fidelity\")."]
    if "bias_sensor_frame_rms_mg" in fid:
        out += ["", "Multi-position labels have no reference: their gravity direction is in the sensor's "
                "own axes, which the truth's apparent bias (in the nominal mount's axes) is not; the row "
                "\"in the sensor's own axes\" compares like with like, the first two rows hold the mount "
                "rotation no fit without a reference can see."]
    if "A_rms_ppm" in fid:
        out += ["", f"Fitted map A against the truth's ({fid['n_maps']} device fits, each entry): "
                f"{fid['A_rms_ppm']:.1f} ppm RMS, {fid['A_max_ppm']:.1f} ppm at most."]
    return out


def _fidelity_section(page: _Page, campaigns: Sequence[str]) -> list[str]:
    lines = ["## Label fidelity (labels against the simulator's truth)", ""]
    if not campaigns:
        return lines + ["No campaign was asked for.", ""]
    lines += ["Label error = label − truth, over every labelled (recording, device), in mg "
              "(1 mg = 9.80665e-3 m/s²).", ""]
    real: list[str] = []
    no_raw: list[str] = []
    for campaign in campaigns:
        labels_dir = page.root / "processed" / "labels" / campaign
        raw_dir = page.root / "raw" / campaign
        truth = truth_dir_of(raw_dir)
        if truth is None:
            (real if raw_dir.is_dir() else no_raw).append(campaign)
            continue
        lines += [f"### {campaign}", ""]
        labels = read_labels(labels_dir) if labels_dir.is_dir() else None
        if labels is None or labels.empty:
            lines += [f"No labels in `{page.shown(labels_dir)}`: nothing to compare.", ""]
            continue
        try:
            fid = label_fidelity(labels, truth)
        except TruthError as exc:
            msg = str(exc).replace(f"{page.root}{os.sep}", "")
            lines += [f"The labels could not be compared with the truth: {msg}", ""]
            continue
        if "bias_rms_mg" not in fid:
            lines += [f"{fid['n']} labels, none with a finite bias: nothing to compare.", ""]
            continue
        offsets = (f", {fid['n_offsets']} of them with a zero-g offset" if "n_offsets" in fid
                   else ", none with a zero-g offset")
        lines += [f"{fid['n']} labels (`{page.shown(labels_dir)}`){offsets}, against "
                  f"`{page.shown(truth)}`.", "", *_fidelity_table(fid), ""]
    if real:
        lines += ["Campaigns without a truth folder: "
                  + ", ".join(f"`{c}` (real data: no truth)" for c in real) + ".", ""]
    if no_raw:
        lines += ["Campaigns without a raw folder (truth unknown): "
                  + ", ".join(f"`{c}` (no `raw/{c}`)" for c in no_raw) + ".", ""]
    return lines


def _dataset_section(page: _Page, campaigns: Sequence[str]) -> list[str]:
    lines = ["## Datasets", ""]
    if not campaigns:
        return lines + ["No campaign was asked for.", ""]
    table = ["| Dataset | Windows | Recordings | Devices | Window (samples) | Protocols | Card |",
             "|---|---:|---:|---|---:|---|---|"]
    absent = []
    for campaign in campaigns:
        folder = page.root / "processed" / "datasets" / campaign
        path = folder / "datapackage.json"
        doc = _load_json(path, page)
        if doc is None:
            absent.append(campaign)
            continue
        try:
            meta = doc["ofbe"]
            devices = ", ".join(sorted(meta.get("devices", {}))) or "–"
            protocols = ", ".join(f"{p} ({int(v['n_folds'])} folds)" if isinstance(v, dict) and "n_folds" in v
                                  else p for p, v in meta.get("protocols", {}).items()) or "–"
            row = (f"| {meta.get('name', campaign)} | {int(meta['n_windows'])} | "
                   f"{int(meta['n_recordings'])} | {devices} | {meta.get('window_length', '–')} | "
                   f"{protocols} | "
                   f"{page.link(folder / 'README.md', 'README.md')}, "
                   f"{page.link(path, 'datapackage.json')} |")
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise _layout_error(path, page, "a data package with an 'ofbe' section", exc) from None
        table.append(row)
    if len(table) > 2:
        lines += [*table, ""]
    if absent:
        lines += ["Not built (no datapackage.json): " + ", ".join(f"`{c}`" for c in absent) + ".", ""]
    return lines


def _training_line(page: _Page, path: Path) -> str:
    doc = _load_json(path, page)
    try:
        folds = doc["folds"]
        dataset = doc.get("dataset", path.parent.parent.name)
        protocol = doc.get("protocol", path.parent.name)
        if not folds:
            return f"- `{dataset}`, protocol `{protocol}`: no folds ({page.link(path, 'training.json')})."
        epochs = [int(f["epochs_run"]) for f in folds]
        best = [int(f["best_epoch"]) for f in folds if f.get("best_epoch") is not None]
        seconds = math.fsum(float(f["seconds"]) for f in folds)
        n_folds = len({int(f["fold"]) for f in folds})
        n_seeds = len({int(f.get("seed", 0)) for f in folds})
    except (KeyError, TypeError, ValueError) as exc:
        raise _layout_error(path, page, "an ofbe-training/1 summary", exc) from None
    best_text = f" (best epoch {_range(best)})" if best else ""
    seeds_text = f" × {n_seeds} seeds" if n_seeds > 1 else ""
    return (f"- `{dataset}`, protocol `{protocol}`: {n_folds} folds{seeds_text}, {_range(epochs)} epochs"
            f"{best_text}, {seconds:.1f} s in total ({page.link(path, 'training.json')}).")


def _training_section(page: _Page) -> list[str]:
    lines = ["## OFBENet training", ""]
    files = sorted((page.root / "models" / "cv").glob("*/*/training.json"))
    if not files:
        return lines + ["No trained models (no `models/cv/<dataset>/<protocol>/training.json`).", ""]
    return lines + [_training_line(page, p) for p in files] + [""]


def _timings_section(timings: dict[str, float] | None) -> list[str]:
    lines = ["## Stage times", ""]
    if timings is None:
        return lines + ["Stage times were not recorded.", ""]
    if not timings:
        return lines + ["The timings file lists no stage.", ""]
    total = math.fsum(timings.values())
    return lines + ["| Stage | Seconds |", "|---|---:|",
                    *(f"| {name} | {sec:.1f} |" for name, sec in timings.items()),
                    f"| **total** | **{total:.1f}** |", ""]


# ----------------------------------------------------------------------------- API


def build_index(root: Path, campaigns: list[str], protocols: list[str], timings: dict[str, float] | None,
                *, profile: str | None = None) -> str:
    """The Markdown of ``reports/index.md``.

    Parameters
    ----------
    root
        Project root (the folder holding ``reports/``, ``processed/``, ``raw/``, ``models/``).
    campaigns
        Campaigns for the label-fidelity and dataset sections, in display order.
    protocols
        Benchmark protocols, in display order; one whose folder is missing is listed as not run.
    timings
        Stage → seconds, in display order, or None when they were not recorded.
    profile
        Name of the run profile, shown in the first paragraph.

    Returns
    -------
    str
        The page; links are relative to ``root/reports``. The same inputs give the same text.

    Raises
    ------
    OfbeError
        ``root/reports`` is not a folder, or an input that exists cannot be read as what it
        should be.
    """
    page = _Page(Path(root))
    if not page.reports.is_dir():
        raise OfbeError(f"{page.reports}: expected the reports folder of a pipeline run, "
                        "found no such folder")
    lines = [
        *_intro_section(campaigns, protocols, profile),
        *_benchmark_section(page, protocols),
        *_convergence_section(page),
        *_small_angle_section(page),
        *_fidelity_section(page, campaigns),
        *_dataset_section(page, campaigns),
        *_training_section(page),
        *_timings_section(timings),
        f"Made by ofbe {__version__} (`{PROG}`).",
        "",
    ]
    return "\n".join(lines)


def write_index(root: Path, out_path: Path, campaigns: list[str], protocols: list[str],
                timings: dict[str, float] | None = None, *, profile: str | None = None) -> str:
    """Build the index (:func:`build_index`) and write it to ``out_path`` atomically.

    The links are relative to ``root/reports``, so ``out_path`` belongs in that folder;
    its parent is created if needed.

    Returns
    -------
    str
        The Markdown written.
    """
    text = build_index(root, campaigns, protocols, timings, profile=profile)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(out_path, text.encode("utf-8"))
    return text


def read_timings(path: str | Path) -> dict[str, float] | None:
    """Stage times from a JSON file ``{"stages": {name: seconds}}``, or None when it does not exist.

    Raises
    ------
    IndexInputError
        The file is not such a document, or a time is not a finite number ≥ 0.
    """
    path = Path(path)
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise IndexInputError(f"{path}: expected {TIMINGS_FORMAT}, found {exc}") from None
    stages = doc.get("stages") if isinstance(doc, dict) else None
    if not isinstance(stages, dict):
        raise IndexInputError(f"{path}: expected {TIMINGS_FORMAT}, found no 'stages' object")
    out: dict[str, float] = {}
    for name, sec in stages.items():
        if isinstance(sec, bool) or not isinstance(sec, int | float) or not math.isfinite(sec) or sec < 0:
            raise IndexInputError(f"{path}: stages.{name}: expected seconds ≥ 0, found {sec!r}")
        out[str(name)] = float(sec)
    return out


