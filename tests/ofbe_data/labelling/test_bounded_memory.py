"""Memory bounded by the file's size (issue 36) and whole-file checks made once (issue 33).

Reading, detection and pose search work in blocks; every result must be the one the single
pass gives, bit for bit, whatever the block size: each block-wise function is run here with
blocks of a few bytes or rows and with the default, and compared. The memory itself is
measured with ``tracemalloc`` (numpy and bytes allocations are traced) on files of a few MB:
the normalised buffer once took a 64-bit running count per byte of the file (4.8 GB for 300
MiB), and detection held the file as a list of strings (2.4 times its size).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.session import main as session_main
from ofbe_data.io.detection import _layout as detect_layout
from ofbe_data.io.detection._layout import TextLines, find_layout, non_blank, split_lines, starting_with
from ofbe_data.io.formats import filebytes
from ofbe_data.io.formats.generic_csv import _normalise, read_generic_csv
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import CsvMapping
from ofbe_data.labelling import label_rows, stationarity
from ofbe_data.labelling.labels import label_session
from ofbe_data.labelling.multiposition import _poses as poses
from ofbe_data.labelling.multiposition._search import direction_groups

TRICKY = (b"\xef\xbb\xbf# logger v1\r\n\r\n  \t\r\nt;ax;ay;az\r\n# comment\n0,5;1,25;-0,5;9,75\r\n"
          b"1,0;1,5;\xff;9,5\n\n1,5;1,0;0,0;9,0\r  2,0 ;0,5; 0,25;9,25\n\xc2\xa0\n2,5;0,0;0,0;9,8")
"""A semicolon file with decimal commas, a byte-order mark, a comment and blank lines (ASCII and
a no-break space) among the data, CR, LF and CRLF line ends, an invalid byte, no final line end."""


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Same shape, dtype and bits (so −0.0 differs from 0.0 and NaN equals itself)."""
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _numbers_file(path: Path, rows: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    t = np.arange(rows) / 100.0
    acc = rng.normal(size=(rows, 3)) * 0.01 + np.array([0.01, -0.02, 0.98])
    lines = [f"{a:.4f},{b:.5f},{c:.5f},{d:.5f}" for a, (b, c, d) in zip(t, acc, strict=True)]
    data = ("time,ax,ay,az\n" + "\n".join(lines) + "\n").encode()
    path.write_bytes(data)
    return data


# --- reading -----------------------------------------------------------------------------------


AXES = {"t": 0, "ax": 1, "ay": 2, "az": 3}


@pytest.mark.parametrize("mapping", [
    CsvMapping(columns={"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, delimiter=";", skip_rows=1,
               comment="#"),
    CsvMapping(columns=AXES, delimiter=";", header=False, skip_rows=4, comment="#"),
    CsvMapping(columns=AXES, delimiter="whitespace", header=False, skip_rows=4, comment="#"),
])
def test_a_file_read_in_blocks_of_a_few_bytes_reads_as_in_one(tmp_path: Path, mapping: CsvMapping,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    data = TRICKY.replace(b",", b".").replace(b";", b" \t ") if mapping.delimiter == "whitespace" else TRICKY
    whole = _normalise(tmp_path / "f.csv", data, mapping)
    path = tmp_path / "f.csv"
    path.write_bytes(data)
    rec = read_generic_csv(path, mapping)
    for block in (1, 3, 7):
        monkeypatch.setattr(filebytes, "SCAN_BLOCK", block)
        buf, line_of, names, preamble = _normalise(path, data, mapping)
        assert buf == whole[0] and _same(line_of, whole[1]) and (names, preamble) == whole[2:]
        again = read_generic_csv(path, mapping)
        assert _same(again.t, rec.t) and _same(again.acc, rec.acc) and _same(again.line, rec.line)
        assert again.diagnostics == rec.diagnostics
    assert whole[0].endswith(b"\n")  # ended here, so the parser never copies the body to end it
    assert rec.n >= 3 and rec.diagnostics.skipped  # the invalid byte's line is skipped, not guessed


def test_a_garbled_file_validated_piece_by_piece_reads_as_in_one(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Every field as bytes through the validating path (a text column makes every line odd), in
    pieces of a few lines: the same samples, skipped lines and messages as in one piece."""
    rng = np.random.default_rng(6)
    lines = [f"{i / 100:.2f},{a:.4f},{b:.4f},{c:.4f},{'rest' if i % 7 else 'walk'}"
             for i, (a, b, c) in enumerate(rng.normal(size=(300, 3)))]
    lines[10], lines[50] = "0.10,1e999,0.0,9.8,rest", "0.50,+0.5, 0.25 ,9.8,r\u00e9st"
    lines[51], lines[120], lines[200] = "0.51,nan,0,9,x", "1.20,0.1,0.2", ""
    path = tmp_path / "g.csv"
    path.write_bytes(("time,ax,ay,az,label\n" + "\n".join(lines) + "\n").encode())
    mapping = CsvMapping(columns={"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, acc_unit="g")
    rec = read_generic_csv(path, mapping)
    monkeypatch.setattr(filebytes, "SCAN_BLOCK", 40)  # pieces of about 40 bytes: a line or two
    again = read_generic_csv(path, mapping)
    assert _same(again.t, rec.t) and _same(again.acc, rec.acc) and _same(again.line, rec.line)
    assert again.diagnostics == rec.diagnostics
    assert [s.line for s in rec.diagnostics.skipped] == [12, 53, 122, 202]  # range, nan, fields, empty
    assert rec.acc[rec.line == 52][0, 0] == 0.5 * G0  # '+0.5' and ' 0.25 ' are numbers


def test_the_normalised_buffer_is_about_one_copy_of_the_file(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(filebytes, "SCAN_BLOCK", 1 << 16)  # blocks far smaller than the file: what grows
    data = _numbers_file(tmp_path / "f.csv", 60_000)  # ~2 MB
    mapping = CsvMapping(columns={"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, comment="#")
    tracemalloc.start()
    try:
        buf, *_ = _normalise(tmp_path / "f.csv", data, mapping)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(buf) == len(data) - 2  # the column line 'c0,c1,c2,c3' for 'time,ax,ay,az'
    assert peak < 1.5 * len(data)  # the buffer and an int64 or two per line (was 17 times the file)


# --- detection ---------------------------------------------------------------------------------


def test_text_lines_are_the_lines_of_the_decoded_text(monkeypatch: pytest.MonkeyPatch) -> None:
    text = TRICKY.decode("utf-8", errors="replace")[1:]  # the byte-order mark dropped
    lines = split_lines(text)
    for block in (1, 2, 5, 1 << 24):
        monkeypatch.setattr(filebytes, "SCAN_BLOCK", block)
        monkeypatch.setattr(detect_layout, "SCAN_BLOCK", block)
        got = TextLines(TRICKY)
        assert len(got) == len(lines) and got[:] == lines and got[-1] == lines[-1]
        assert list(non_blank(got)) == [bool(line.strip()) for line in lines]
        for prefix in ("#", "1,", "  ", "t;"):
            assert list(starting_with(got, prefix)) == [line.startswith(prefix) for line in lines]
    with pytest.raises(IndexError):
        TextLines(TRICKY)[len(lines)]


def test_detection_finds_the_layout_of_the_list_without_holding_one(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(filebytes, "SCAN_BLOCK", 1 << 16)
    monkeypatch.setattr(detect_layout, "SCAN_BLOCK", 1 << 16)
    data = _numbers_file(tmp_path / "f.csv", 60_000)
    lines = split_lines(data.decode())
    tracemalloc.start()
    try:
        text_lines = TextLines(data)
        found = find_layout(tmp_path / "f.csv", text_lines)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert repr(found) == repr(find_layout(tmp_path / "f.csv", lines))
    assert peak < 1.0 * len(data)  # an int64 or two per line (the list of lines: 2.4 times the file)


# --- pose search and static detection ----------------------------------------------------------


def _signal(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = np.round(rng.normal(size=(n, 3)) * 2.0) * 0.0383 + np.array([0.1, -0.2, G0])
    x[rng.random((n, 3)) < 0.05] = -0.0  # signed zeros: the carried sums must keep them
    return x


@pytest.mark.parametrize("block", [1, 3, 64])
def test_moving_statistics_in_blocks_are_the_one_pass_ones(block: int,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    x = _signal(700, block)
    whole = poses.moving_stats(x, 25), stationarity.moving_variance_norm(x, 50), stationarity.column_mean(x)
    mean, sums = stationarity.centred_sums(x)
    with_sums = stationarity.moving_variance_norm(x, 50, mean, sums)
    quiet = poses.quiet_windows(*whole[0], 25, float(np.median(whole[0][1])), 4.0)
    monkeypatch.setattr(poses, "BLOCK", block)
    monkeypatch.setattr(stationarity, "BLOCK", block)
    means, var = poses.moving_stats(x, 25)
    assert _same(means, whole[0][0]) and _same(var, whole[0][1])
    assert _same(poses.quiet_windows(means, var, 25, float(np.median(var)), 4.0), quiet)
    assert _same(stationarity.moving_variance_norm(x, 50), whole[1])
    assert _same(stationarity.moving_variance_norm(x, 50, mean, sums), with_sums)
    assert _same(stationarity.column_mean(x), whole[2]) and _same(stationarity.column_mean(x), x.mean(axis=0))
    again = stationarity.centred_sums(x)
    assert _same(again[0], mean) and _same(again[1], sums)


def test_static_runs_are_the_samples_some_quiet_window_holds() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        quiet = rng.random(int(rng.integers(0, 200))) < rng.random()
        window = int(rng.integers(1, 12))
        static = np.zeros(quiet.size + window - 1 if quiet.size else 0, dtype=bool)
        for j in np.flatnonzero(quiet):
            static[j:j + window] = True
        edges = np.flatnonzero(np.diff(np.concatenate(([0], static.astype(np.int8), [0])))).reshape(-1, 2)
        got = poses.static_runs(quiet, window)
        assert got.dtype == np.int64 and got.shape == edges.shape and np.array_equal(got, edges)


def test_direction_groups_join_the_first_group_within_the_tolerance() -> None:
    rng = np.random.default_rng(4)
    faces = np.vstack([np.eye(3), -np.eye(3)]) * G0
    means = faces[rng.integers(0, 6, 300)] + rng.normal(size=(300, 3)) * 1.0
    units = means / np.linalg.norm(means, axis=1, keepdims=True)
    expected: list[list[int]] = []
    tolerance = np.cos(np.radians(10.0))
    for i, u in enumerate(units):  # the definition, pose by pose and group by group
        group = next((g for g in expected if float(np.sum(u * units[g[0]])) >= tolerance), None)
        if group is None:
            expected.append([i])
        else:
            group.append(i)
    assert direction_groups(means) == expected and len(expected) > 6


def test_a_whole_file_check_is_made_once_however_many_poses(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """The plausibility of a file's norms is a pass over all of it: asked for by each pose, it
    took 17.5 min on a 20-hour file with thousands of still periods (issue 33)."""
    rng = np.random.default_rng(5)
    fs, parts = 100.0, []
    directions = np.vstack([np.eye(3), -np.eye(3), rng.normal(size=(6, 3))])
    for u in directions / np.linalg.norm(directions, axis=1, keepdims=True):
        parts += [np.tile(u, (int(2.5 * fs), 1)), u + 0.3 * rng.normal(size=(int(fs), 3))]
    acc = np.vstack(parts) * 1.01 + 0.002 + 0.0005 * rng.normal(size=(sum(map(len, parts)), 3))
    session = tmp_path / "camp" / "s1"
    session.mkdir(parents=True)
    lines = "\n".join(f"{i / fs:.2f},{a:.4f},{b:.4f},{c:.4f}" for i, (a, b, c) in enumerate(acc))
    (session / "imu.csv").write_text("time,ax,ay,az\n" + lines + "\n")
    assert session_main(["init", str(session), "--kind", "multi-position"]) == 0
    calls = []
    real = label_rows.typical_norm_problem
    monkeypatch.setattr(label_rows, "typical_norm_problem", lambda *a, **k: calls.append(1) or real(*a, **k))
    labels = label_session(session)
    assert len(labels.rows) + len(labels.rejections) >= 12  # a row or a rejection per pose found
    assert len(calls) <= 2  # the file's own check, and once more for all its poses
