"""Issue 36: a file read with ``sort_by_time: true`` whose rows still repeat time stamps was
rejected with the advice to set ``sort_by_time: true``. Sorted rows never run backwards, so what
is left are repeats: the rejection says so and what to do instead."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ofbe_data.labelling.labels import LabelParams, label_session

MANIFEST = ("format: ofbe-session/1\ncampaign: camp\nsession: s1\nkind: gravity-aligned\n"
            "site: {gravity_mps2: 9.80665}\npower_cycle: 1\ndevices:\n  dut:\n    model: X\n"
            "    role: dut\n    format: csv\n    columns: {t: t, ax: ax, ay: ay, az: az}\n{extra}"
            "recordings:\n  - id: r1\n    files: {dut: r1.csv}\n")


def _session(tmp_path: Path, extra: str) -> Path:
    """3000 rows at 100 Hz grouped by part (the later half first), every 20th row written twice."""
    rng = np.random.default_rng(36)
    n = 3000
    acc = np.array([0.03, -0.02, 9.83]) + 0.01 * rng.standard_normal((n, 3))
    lines = [f"{i / 100:.2f},{'b' if i < n // 2 else 'a'},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}"
             for i, a in enumerate(acc)]
    lines = [ln for i, line in enumerate(lines) for ln in ([line, line] if i % 20 == 0 else [line])]
    by_part = sorted(lines, key=lambda ln: ln.split(",")[1])
    folder = tmp_path / "camp" / "s1"
    folder.mkdir(parents=True)
    (folder / "r1.csv").write_text("t,part,ax,ay,az\n" + "\n".join(by_part) + "\n")
    (folder / "session.yaml").write_text(MANIFEST.replace("{extra}", extra))
    return folder


def test_sorted_rows_that_repeat_time_stamps_are_not_advised_to_sort(tmp_path: Path) -> None:
    folder = _session(tmp_path, "    sort_by_time: true\n")
    (rej,) = label_session(folder, LabelParams(min_samples=1000)).rejections
    assert (rej.reason, rej.detail) == ("garbled", (
        "150 of 3150 data lines skipped (4.76% > 1.00%): 150 with a time stamp that repeats an earlier one "
        "(sort_by_time: true is set, so the rows are read in time order and none runs backwards: duplicated "
        "lines, or a clock coarser than the sample period; remove the duplicated lines, or log the time with "
        "more digits; the file itself is never changed)"))


def test_unsorted_rows_are_still_advised_to_sort(tmp_path: Path) -> None:
    folder = _session(tmp_path / "unsorted", "")
    (rej,) = label_session(folder, LabelParams(min_samples=1000)).rejections
    # part b (1575 lines) runs backwards after part a, whose 75 repeats are dropped too
    assert rej.reason == "garbled" and rej.detail.startswith("1650 of 3150 data lines skipped")
    assert "read in time order with sort_by_time: true" in rej.detail
