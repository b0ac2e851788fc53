"""A few garbled lines set apart (typed parse for the rest) give exactly the validating path's
rows, values, lines and skipped lines, or the reader falls back to that path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ofbe_data.io.formats.common import Body, _Rows, read_body
from ofbe_data.io.formats.oddlines import long_digit_run, split_odd_lines

HEADER = b"t_us,ax,ay,az\n"
INTS = {"t_us": "int", "ax": "int", "ay": "int", "az": "int"}
FLOATS = {"t_us": "float", "ax": "float", "ay": "float", "az": "float"}


def _lines(n: int = 400) -> list[bytes]:
    rng = np.random.default_rng(3)
    return [b"%d,%d,%d,%d" % (1000 * i, *rng.integers(-300, 300, 3)) for i in range(n)]


GARBLE = {
    "stray byte": {17: b"13@0140,1,2,3"},
    "non-ascii": {5: b"12\xff\xfe,1,2,3", 300: b"\xe2\x82\xac,1,2,3"},
    "hash and short": {40: b"40000,1,2#1", 41: b"41000,1"},
    "valid with spaces": {60: b" 60000 , 1, 2, 3"},
    "field count in the clean part": {7: b"7000,1,2,3,4", 90: b"9x,1,2,3"},
    "empty field": {11: b"11000,,2,3", 12: b"1200?,1,2,3"},
    "empty line": {20: b"", 21: b"@"},
    "tiny exponent": {30: b"30000,1e-1234,2,3", 31: b"31000,1,2,3!"},
    "long integer": {33: b"0000000000000000000033000,1,2,3", 34: b"x,1,2,3"},
    "plus sign": {35: b"+35000,1,2,3", 36: b"36000,1,2,3z"},
    "last line": {399: b"399000,1,2,3?"},
}


def _body(case: str, n: int = 400) -> bytes:
    lines = _lines(n)
    for i, text in GARBLE[case].items():
        lines[i] = text
    return HEADER + b"\n".join(lines) + b"\n"


def _same(a: Body, b: Body) -> None:
    assert a.lines.tobytes() == b.lines.tobytes() and a.lines_read == b.lines_read
    assert a.skipped == b.skipped
    assert sorted(a.values) == sorted(b.values)
    for k in a.values:
        assert a.values[k].dtype == b.values[k].dtype and a.values[k].tobytes() == b.values[k].tobytes()


@pytest.mark.parametrize("case", sorted(GARBLE))
@pytest.mark.parametrize("wanted", [INTS, FLOATS])
@pytest.mark.parametrize("header_line", [1, 7])
def test_odd_lines_apart_give_the_validating_paths_result(case: str, wanted: dict[str, str],
                                                          header_line: int) -> None:
    body = _body(case)
    rows = _Rows(Path("x.csv"), ["t_us", "ax", "ay", "az"], ",", wanted)
    lines_read = body.count(b"\n") - 1
    full = rows.validated(body, header_line, lines_read)
    split = split_odd_lines(body, len(HEADER), ",")
    assert split is not None
    around = rows.around(split, header_line, lines_read)
    if around is not None:
        _same(around, full)
    # and through the reader's entry point, with a preamble before the column line
    data = b"# a\n" * (header_line - 1) + body
    _same(read_body(Path("x.csv"), data, data.index(HEADER), header_line, ",", wanted), full)


def test_cases_that_must_fall_back_do() -> None:
    rows = _Rows(Path("x.csv"), ["t_us", "ax", "ay", "az"], ",", FLOATS)
    for case in ("valid with spaces", "tiny exponent", "empty field"):
        body = _body(case)
        split = split_odd_lines(body, len(HEADER), ",")
        assert split is not None and rows.around(split, 1, body.count(b"\n") - 1) is None, case
    body = _body("stray byte")
    assert rows.around(split_odd_lines(body, len(HEADER), ","), 1, body.count(b"\n") - 1) is not None


def test_split_declines_other_line_ends_and_clean_bodies() -> None:
    body = _body("stray byte")
    assert split_odd_lines(body.replace(b"\n", b"\r\n"), len(HEADER) + 1, ",") is None
    assert split_odd_lines(body[:-1], len(HEADER), ",") is None
    assert split_odd_lines(HEADER + b"\n".join(_lines()) + b"\n", len(HEADER), ",") is None
    assert long_digit_run(b"1," + b"9" * 19) and not long_digit_run(b"9" * 18 + b",1")
