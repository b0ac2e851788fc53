"""Issue 36: epoch nanoseconds written in scientific notation became a 10 Hz manifest with no word
about lost precision. ``ofbe-session init`` now names time stamps written with too few digits
for their sample period (the file, the line, the significant digits kept) and advises integers;
the manifest's comments on the time unit and the rate carry the word."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.session import main
from ofbe_data.io.detection._time import lost_precision, text_quantum

N = 3000
FS = 100.0
EPOCH_NS = 1_700_000_000_123_000_000
ADVICE = ("(scientific notation or float64 keep too few digits); export the time as integers (e.g. epoch "
          "nanoseconds written in full, not in scientific notation)")


def _folder(tmp_path: Path, stamp: Callable[[int], str], name: str = "time_ns") -> tuple[Path, Path]:
    """A session folder of one csv: N still samples at 100 Hz, time written by ``stamp(i)``."""
    rng = np.random.default_rng(36)
    acc = np.array([0.03, -0.02, 9.83]) + 0.01 * rng.standard_normal((N, 3))
    rows = [f"{stamp(i)},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}" for i, a in enumerate(acc)]
    folder = tmp_path / "lab" / "s1"
    folder.mkdir(parents=True)
    path = folder / "r1.csv"
    path.write_text(f"{name},ax,ay,az\n" + "\n".join(rows) + "\n")
    return folder, path


def _init(capsys, folder: Path) -> tuple[int, str, str]:
    code = main(["init", str(folder), "--power-cycle", "1", "--gravity", "9.80665"])
    captured = capsys.readouterr()
    manifest = (folder / "session.yaml").read_text() if (folder / "session.yaml").exists() else ""
    return code, captured.err, manifest


def _precision_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "significant digits" in line]


def test_epoch_ns_in_scientific_notation_coarser_than_the_period(tmp_path, capsys) -> None:
    """11 significant digits of epoch ns step by 0.1 s: nine samples in ten share a stamp."""
    folder, path = _folder(tmp_path, lambda i: f"{float(EPOCH_NS + i * 10_000_000):.10e}")
    code, err, manifest = _init(capsys, folder)
    assert code == 0
    steps = ("they step by 1e+08 ns (0.1 s) at the finest, 10 times the sample period of about 1e+07 ns (the "
             "rows' span gives 99.967 Hz)")
    assert _precision_lines(err) == [
        f"ofbe-session: warning: {path}: line 2: 'time_ns' keeps only 11 significant digits "
        f"('1.7000000001e+18'): {steps}: 2699 of 2999 steps do not advance, so the rate measured from the "
        f"steps (10 Hz) is wrong {ADVICE}"]
    note = ("lost precision: the time stamps keep only 11 significant digits (line 2: '1.7000000001e+18'): "
            + steps)
    time_line = next(line for line in manifest.splitlines() if line.strip().startswith("time_unit:"))
    rate_line = next(line for line in manifest.splitlines() if "rate 10 Hz" in line)
    assert time_line.endswith(f"; {note}") and rate_line.endswith(f"; {note})")


def test_thirteen_digits_are_named_as_a_share_of_the_step(tmp_path, capsys) -> None:
    """'1.700000000123e+18': 1 ms steps of a 10 ms period; the rate is right, each step 10 % off."""
    folder, path = _folder(tmp_path, lambda i: f"{float(EPOCH_NS + i * 10_000_000):.12e}")
    code, err, _ = _init(capsys, folder)
    assert code == 0
    assert _precision_lines(err) == [
        f"ofbe-session: warning: {path}: line 2: 'time_ns' keeps only 13 significant digits "
        "('1.700000000123e+18'): they step by 1e+06 ns (0.001 s) at the finest, 10 % of the sample period of "
        "about 1e+07 ns (the rows' span gives 100 Hz): each step is off by up to that much " + ADVICE]


@pytest.mark.parametrize(("name", "stamp"), [
    ("time_ns", lambda i: str(EPOCH_NS + i * 10_000_000)),  # integers: exact
    ("t", lambda i: f"{i / FS:.2f}"),  # seconds with the period's own resolution
    ("t", lambda i: f"{i / FS:.7e}"),  # scientific notation with digits to spare
])
def test_stamps_with_enough_digits_are_not_named(tmp_path, capsys, name, stamp) -> None:
    folder, _ = _folder(tmp_path, stamp, name)
    code, err, manifest = _init(capsys, folder)
    assert code == 0 and _precision_lines(err) == [] and "lost precision" not in manifest
    assert "rate 100 Hz" in manifest


def test_six_digits_of_epoch_seconds_never_advance(tmp_path, capsys) -> None:
    folder, path = _folder(tmp_path, lambda i: f"{1_700_000_000.123 + i / FS:.5e}", "time")
    code, err, manifest = _init(capsys, folder)
    assert code == 2 and manifest == ""
    assert err == (f"ofbe-session: error: {path}: 'time' does not advance (no positive step): every stamp "
                   "reads '1.70000e+09' from line 2, 6 significant digits in scientific notation (lost "
                   "precision: export the time as integers, e.g. epoch nanoseconds written in full): give "
                   "--time-column NAME, or --rate HZ when the file has no time column\n")


def test_the_finest_step_a_text_shows() -> None:
    assert text_quantum("1.7000000001e+18") == (1e8, True)
    assert text_quantum("12.345") == (pytest.approx(1e-3), False)
    assert text_quantum("-3") == (1.0, False)
    assert text_quantum("1e-3") == (pytest.approx(1e-3), True)
    assert text_quantum("abc") is None and text_quantum(".") is None
    # float64 itself: full-digit epoch ns read as floats step by 256 ns, 0.0026 % of a 10 ms period
    t = (EPOCH_NS + np.arange(N) * 10_000_000).astype(np.float64)
    stamps = [(2 + i, f"{EPOCH_NS + i * 10_000_000}.0") for i in range(10)]
    assert lost_precision(stamps, t, exact=False) is None
    # ... but 256 ns of a 20 µs period (50 kHz would be refused; 1.3 %) is named
    t = (EPOCH_NS + np.arange(N) * 20_000).astype(np.float64)
    stamps = [(2 + i, f"{EPOCH_NS + i * 20_000}.0") for i in range(10)]
    lost = lost_precision(stamps, t, exact=False)
    assert lost is not None and lost.quantum == 256.0 and lost.digits == 17
