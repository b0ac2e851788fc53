"""``ofbe-session init`` on a corpus of the file shapes labs really produce (issue 22, item 5).

Each shape writes one small file of that shape into a session folder, with known true
acceleration (the numbers written, times their unit's exact scale), units and rate, runs ``init``
through the command line's ``main``, then loads the manifest and reads the file through it with
the reader ``check`` and labelling use, and asserts the acceleration in m/s², the rate and each
device's columns. Shapes ``init`` cannot settle (raw counts of an unknown scale, no time column
and no rate…) must stop with the usage exit status and one line naming the one flag to give;
given that flag, they decide correctly too.

The score (shapes decided correctly with no flag at all: 35 of 43) is asserted by
``test_the_corpus_is_decided_unaided``; the whole corpus runs in about 10 s.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ofbe_data.cli.session import main
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest

N = 3000
"""Samples per file (30 s at 100 Hz)."""
FS = 100.0
EPOCH_NS = 1_741_947_751_000_000_000
BIAS = np.array([0.05, -0.08, 0.12])


@dataclass(frozen=True)
class Device:
    """What one device of the manifest must be.

    Attributes
    ----------
    columns
        Its ``columns`` exactly.
    acc
        (rows, 3) the true specific force of every row the reader must return, m/s².
    gyro
        (rows, 3) the true angular rate, rad/s, or None: the manifest must map no gyroscope.
    keys
        Further manifest keys the entry must hold (``comment``, ``time_unit``…).
    """

    columns: dict[str, str | int]
    acc: np.ndarray
    gyro: np.ndarray | None = None
    keys: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Shape:
    """One file shape and what ``init`` must make of it.

    Attributes
    ----------
    text
        The file's bytes.
    rate_hz
        The true sample rate.
    devices
        Device id → what it must be.
    flags
        Flags given to ``init`` (none for the shapes it must decide unaided).
    refusal
        For a shape ``init`` cannot settle: the exact error after ``<file>: ``; ``flags`` then
        settle it.
    said
        Texts the printed evidence (stdout) must hold.
    warned
        Texts the warnings (stderr) must hold.
    rate_tol
        Relative tolerance of the measured rate (host and phone clocks jitter).
    """

    text: bytes
    rate_hz: float
    devices: dict[str, Device]
    flags: tuple[str, ...] = ()
    refusal: str | None = None
    said: tuple[str, ...] = ()
    warned: tuple[str, ...] = ()
    rate_tol: float = 1e-6


SHAPES: dict[str, Callable[[], Shape]] = {}


def shape(fn: Callable[[], Shape]) -> Callable[[], Shape]:
    """Register a shape under its function's name (underscores as dashes)."""
    SHAPES[fn.__name__.replace("_", "-")] = fn
    return fn


# --------------------------------------------------------------------------- signals


def still(seed: int, up: tuple[float, float, float] = (0.0, 0.0, 1.0), n: int = N) -> np.ndarray:
    """(n, 3) specific force of a device at rest, m/s²: g0 along ``up``, a bias, 2 mg of noise."""
    u = np.asarray(up, dtype=np.float64)
    rng = np.random.default_rng(seed)
    return G0 * u / np.linalg.norm(u) + BIAS + rng.normal(0.0, 0.02, (n, 3))


def spin(seed: int, n: int = N, peak: float = 150.0) -> np.ndarray:
    """(n, 3) angular rate in °/s: a small bias and noise, and one turn about z at ``peak`` °/s."""
    rng = np.random.default_rng(seed)
    w = np.array([0.2, -0.1, 0.15]) + rng.normal(0.0, 0.05, (n, 3))
    w[n // 2:n // 2 + 60, 2] += peak
    return w


def poses(seed: int, n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """A multi-position recording (imu_tk's kind): six faces held still, turned at about 1.6 rad/s
    between them. Returns the specific force (m/s²) and the angular rate (rad/s)."""
    faces = [(0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 0, -1), (-1, 0, 0), (0, -1, 0)]
    rng = np.random.default_rng(seed)
    per = n // len(faces)
    acc = np.zeros((n, 3))
    gyro = rng.normal(0.0, 0.003, (n, 3))
    for k, face in enumerate(faces):
        a, b = k * per, (k + 1) * per if k < len(faces) - 1 else n
        acc[a:b] = G0 * np.asarray(face, dtype=np.float64)
        if k:
            prev = G0 * np.asarray(faces[k - 1], dtype=np.float64)
            turn = np.linspace(0.0, 1.0, 100)[:, None]
            acc[a:a + 100] = prev * (1 - turn) + acc[a] * turn
            gyro[a:a + 100, k % 3] += 1.6
    return acc + BIAS + rng.normal(0.0, 0.02, (n, 3)), gyro


def t_s(n: int = N, fs: float = FS) -> np.ndarray:
    return np.arange(n) / fs


def jittered(seed: int, n: int = N, spread: float = 0.3) -> np.ndarray:
    """Phone or host-clock stamps, s: 10 ms steps ± ``spread`` of a step."""
    rng = np.random.default_rng(seed)
    return np.concatenate(([0.0], np.cumsum(0.01 * (1 + spread * rng.uniform(-1, 1, n - 1)))))


def q(x: np.ndarray, decimals: int) -> np.ndarray:
    """Values as written with ``decimals`` decimals."""
    return np.round(x, decimals)


def lines(cols: list[np.ndarray], fmts: list[str], sep: str) -> list[str]:
    """Data lines (no line ends)."""
    return [sep.join(f.format(c[i]) for f, c in zip(fmts, cols, strict=True))
            for i in range(cols[0].shape[0])]


def text(head: list[str], body: list[str], end: str = "\n", bom: bool = False) -> bytes:
    return (("\ufeff" if bom else "") + end.join(head + body) + end).encode("utf-8")


def comma(body: list[str]) -> list[str]:
    """Decimal commas (a semicolon delimiter)."""
    return [line.replace(".", ",") for line in body]


def axes(acc: np.ndarray) -> list[np.ndarray]:
    return [acc[:, 0], acc[:, 1], acc[:, 2]]


# --------------------------------------------------------------------------- names labs use


@shape
def accel_caps_gyro_dps() -> Shape:
    """An IMU board's upper-case names, gyroscope in °/s (a turn settles the unit)."""
    acc, w = q(still(1), 5), q(spin(1), 3)
    body = lines([t_s(), *axes(acc), *axes(w)], ["{:.2f}"] + ["{:.5f}"] * 3 + ["{:.3f}"] * 3, ",")
    head = ["TIME,ACCEL_X,ACCEL_Y,ACCEL_Z,GYRO_X,GYRO_Y,GYRO_Z"]
    cols = {"t": "TIME", "ax": "ACCEL_X", "ay": "ACCEL_Y", "az": "ACCEL_Z", "gx": "GYRO_X", "gy": "GYRO_Y",
            "gz": "GYRO_Z"}
    return Shape(text(head, body), FS, {"dut": Device(cols, acc, np.radians(w), {"gyro_unit": "deg/s"})},
                 said=("gyro_unit: deg/s (peak |ω| 150",))


@shape
def acc_digit_axes() -> Shape:
    """``acc_0, acc_1, acc_2``: axes numbered, time in integer milliseconds, values in g."""
    g = q(still(2) / G0, 6)
    body = lines([np.arange(N) * 10, *axes(g)], ["{:d}"] + ["{:.6f}"] * 3, ",")
    cols = {"t": "timestamp_ms", "ax": "acc_0", "ay": "acc_1", "az": "acc_2"}
    return Shape(text(["timestamp_ms,acc_0,acc_1,acc_2"], body), FS,
                 {"dut": Device(cols, g * G0, keys={"time_unit": "ms", "acc_unit": "g"})},
                 said=("(axes numbered 0, 1, 2)",))


@shape
def numbered_channels() -> Shape:
    """``ch_0, ch_1, ch_2`` (``*_0/_1/_2`` of a word naming nothing): the only triad, in mg."""
    mg = q(still(3) / G0 * 1000, 2)
    body = lines([t_s(), *axes(mg)], ["{:.2f}"] + ["{:.2f}"] * 3, ",")
    cols = {"t": "t", "ax": "ch_0", "ay": "ch_1", "az": "ch_2"}
    return Shape(text(["t,ch_0,ch_1,ch_2"], body), FS, {"dut": Device(cols, mg * G0 / 1000,
                                                                      keys={"acc_unit": "mg"})},
                 said=("the only x/y/z triad of the file",))


@shape
def bracket_index() -> Shape:
    """``accel[0]…`` as numpy and MATLAB exports name a vector's elements."""
    acc = q(still(4), 5)
    body = lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.5f}"] * 3, ",")
    cols = {"t": "time", "ax": "accel[0]", "ay": "accel[1]", "az": "accel[2]"}
    return Shape(text(["time,accel[0],accel[1],accel[2]"], body), FS, {"dut": Device(cols, acc)})


# --------------------------------------------------------------------------- odd lines


@shape
def column_numbers() -> Shape:
    """A first line ``1,2,3,4`` numbering the columns, then data without names."""
    acc = q(still(5), 5)
    body = lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.5f}"] * 3, ",")
    return Shape(text(["1,2,3,4"], body), FS, {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3}, acc,
                                                             keys={"header": False, "skip_rows": 1})},
                 said=("line 1 ('1,2,3,4') numbers the columns",))


@shape
def column_numbers_imu() -> Shape:
    """Tab-separated, columns numbered 1–9: index, time, acceleration, angular rate, temperature;
    the gyroscope's unit cannot be told at rest, so it is not mapped (and init says so)."""
    acc, w = q(still(6), 5), q(np.radians(spin(6, peak=0.0)), 5)
    temp = np.full(N, 31.5)
    body = lines([np.arange(N), t_s(), *axes(acc), *axes(w), temp], ["{:d}", "{:.2f}"] + ["{:.5f}"] * 6
                 + ["{:.1f}"], "\t")
    return Shape(text(["\t".join(str(k) for k in range(1, 10))], body), FS,
                 {"dut": Device({"t": 1, "ax": 2, "ay": 3, "az": 4}, acc, keys={"skip_rows": 1})},
                 said=("gyro: not mapped (by position: columns 5, 6, 7",))


@shape
def repl_prompts() -> Shape:
    """A MicroPython REPL capture: ``>>>`` and ``> `` prompt lines before and inside the data."""
    acc = q(still(7), 5)
    body = lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.5f}"] * 3, ",")
    body.insert(1000, "> paused")
    body.insert(2001, ">>> imu.resume()")
    head = [">>> import imu", ">>> imu.log()", "t,ax,ay,az"]
    return Shape(text(head, body), FS, {"dut": Device({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, acc,
                                                      keys={"comment": ">"})},
                 said=("comment: > (", "comment or prompt lines, not garbled data"))


@shape
def slash_markers() -> Shape:
    """``// marker`` lines among whitespace-separated data."""
    acc = q(still(8), 5)
    body = lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.5f}"] * 3, "  ")
    body.insert(1500, "// marker 1")
    return Shape(text(["time  ax  ay  az"], body), FS,
                 {"dut": Device({"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, acc,
                                keys={"comment": "//", "delimiter": "whitespace"})})


@shape
def unit_row() -> Shape:
    """A unit row under the column line (``s,g,g,g``): the names are the line above it."""
    g = q(still(9) / G0, 6)
    body = lines([t_s(), *axes(g)], ["{:.2f}"] + ["{:.6f}"] * 3, ",")
    return Shape(text(["time,ax,ay,az", "s,g,g,g"], body), FS,
                 {"dut": Device({"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, g * G0,
                                keys={"comment": "s,g,g,g", "acc_unit": "g", "time_unit": "s"})},
                 said=("line 2 under the column line states the units",))


@shape
def unit_row_excel() -> Shape:
    """An Excel sheet saved as CSV: BOM, CRLF, ``;`` and decimal commas, a bracketed unit row."""
    acc = q(still(10), 4)
    body = comma(lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.4f}"] * 3, ";"))
    unit = "[s];[m/s²];[m/s²];[m/s²]"
    return Shape(text(["Zeit;AccX;AccY;AccZ", unit], body, "\r\n", bom=True), FS,
                 {"dut": Device({"t": "Zeit", "ax": "AccX", "ay": "AccY", "az": "AccZ"}, acc,
                                keys={"comment": unit, "delimiter": ";", "acc_unit": "m/s2"})})


@shape
def excel_ansi_code_page() -> Shape:
    """Excel's plain "CSV" on Windows: Windows-1252 (``m/s²`` is byte B2, not UTF-8), a unit row,
    ``;`` and decimal commas, CRLF. The reader takes no such column line, so the manifest skips the
    two lines and names the columns by index."""
    acc = q(still(46), 4)
    body = comma(lines([t_s(), *axes(acc)], ["{:.2f}"] + ["{:.4f}"] * 3, ";"))
    head = ["Zeit;Beschleunigung X;Beschleunigung Y;Beschleunigung Z", "[s];[m/s²];[m/s²];[m/s²]"]
    return Shape("\r\n".join(head + body).encode("cp1252") + b"\r\n", FS,
                 {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3}, acc,
                                keys={"header": False, "skip_rows": 2, "delimiter": ";"})},
                 said=("is not UTF-8 text (a Windows code page?)",))


@shape
def unit_row_and_prompts() -> Shape:
    """A unit row and prompt lines: the comment key goes to the prompts, the reader skips the unit
    row as one unreadable line (no key skips a line after the column line)."""
    g = q(still(11) / G0, 6)
    body = lines([t_s(), *axes(g)], ["{:.2f}"] + ["{:.6f}"] * 3, ",")
    body.insert(700, "> mark")
    return Shape(text(["t,ax,ay,az", "s,g,g,g"], body), FS,
                 {"dut": Device({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, g * G0,
                                keys={"comment": ">", "acc_unit": "g"})},
                 said=("unit_row: 2 (line 2 under the column line states the units",))


# --------------------------------------------------------------------------- units and rates


@shape
def t_ms_holds_seconds() -> Shape:
    """``t_ms`` holding seconds: read as ms it would be 100 kHz, so seconds, with a warning."""
    acc = q(still(12), 5)
    body = lines([t_s(), *axes(acc)], ["{:.3f}"] + ["{:.5f}"] * 3, ",")
    return Shape(text(["t_ms,ax,ay,az"], body), FS,
                 {"dut": Device({"t": "t_ms", "ax": "ax", "ay": "ay", "az": "az"}, acc,
                                keys={"time_unit": "s"})},
                 warned=("the column name 't_ms' says ms, but its median step 0.01 would give 1e+05 Hz, "
                         "outside the 0.5–20000 Hz an accelerometer logs at; in s it gives 100 Hz",))


@shape
def time_s_holds_ms() -> Shape:
    """``time_s`` holding milliseconds (0.1 Hz as seconds): milliseconds."""
    acc = q(still(13), 5)
    body = lines([t_s() * 1000, *axes(acc)], ["{:.1f}"] + ["{:.5f}"] * 3, ",")
    return Shape(text(["time_s,ax,ay,az"], body), FS,
                 {"dut": Device({"t": "time_s", "ax": "ax", "ay": "ay", "az": "az"}, acc,
                                keys={"time_unit": "ms"})}, warned=("in ms it gives 100 Hz",))


@shape
def epoch_nanoseconds() -> Shape:
    """Unix epoch nanoseconds (19 digits, beyond float64's integers)."""
    acc = q(still(14), 5)
    ns = EPOCH_NS + np.arange(N, dtype=np.int64) * 10_000_000
    body = lines([ns, *axes(acc)], ["{:d}"] + ["{:.5f}"] * 3, ",")
    return Shape(text(["timestamp,acc_x,acc_y,acc_z"], body), FS,
                 {"dut": Device({"t": "timestamp", "ax": "acc_x", "ay": "acc_y", "az": "acc_z"}, acc,
                                keys={"time_unit": "ns"})}, said=("epoch nanoseconds",))


@shape
def host_clock() -> Shape:
    """Epoch seconds from a host clock: 20 % jitter and two lost lines (gaps)."""
    g = q(still(15) / G0, 6)
    stamps = 1_741_947_751.0 + jittered(15, spread=0.2)
    keep = np.ones(N, dtype=bool)
    keep[[900, 2100]] = False  # two lines the host never got
    body = lines([stamps[keep], *axes(g[keep])], ["{:.6f}"] + ["{:.6f}"] * 3, ",")
    return Shape(text(["time,ax,ay,az"], body), FS,
                 {"dut": Device({"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, g[keep] * G0,
                                keys={"time_unit": "s", "acc_unit": "g"})}, rate_tol=0.01,
                 said=("the mean rate, as check reports it",))


@shape
def milli_g_suffix() -> Shape:
    """``AccX_mg``: the unit in a name suffix."""
    mg = q(still(16) / G0 * 1000, 1)
    body = lines([t_s(), *axes(mg)], ["{:.2f}"] + ["{:.1f}"] * 3, ",")
    return Shape(text(["t,AccX_mg,AccY_mg,AccZ_mg"], body), FS,
                 {"dut": Device({"t": "t", "ax": "AccX_mg", "ay": "AccY_mg", "az": "AccZ_mg"}, mg * G0 / 1000,
                                keys={"acc_unit": "mg"})}, said=("the column names say so",))


@shape
def counts_with_unit_flag() -> Shape:
    """Signed counts at 4096 per g with ``--unit counts``: the counts per g come from the norm."""
    counts = np.rint(still(17) / G0 * 4096)
    body = lines([t_s(), *axes(counts)], ["{:.2f}"] + ["{:.0f}"] * 3, ",")
    return Shape(text(["t,ax,ay,az"], body), FS,
                 {"dut": Device({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, counts / 4096 * G0,
                                keys={"acc_unit": "counts", "lsb_per_g": 4096.0})},
                 flags=("--unit", "counts"))


@shape
def offset_binary_16bit() -> Shape:
    """An unsigned 16-bit converter, blank-separated, no header: zero at mid-scale 32768."""
    counts = np.rint(still(18) / G0 * 16384) + 32768
    body = lines([np.arange(N) * 10, *axes(counts)], ["{:>9d}"] + ["{:>7.0f}"] * 3, " ")
    return Shape(text([], body), FS, {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3},
                                                    (counts - 32768) / 16384 * G0,
                                                    keys={"acc_unit": "counts", "zero_counts": 32768.0,
                                                          "time_unit": "ms", "delimiter": "whitespace"})})


# --------------------------------------------------------------------------- two accelerometers


@shape
def two_triads_semicolon() -> Shape:
    """``t;a1x;a1y;a1z;a2x;a2y;a2z``: two devices reading one file."""
    a1, a2 = q(still(19), 5), q(still(20, up=(0.0, 0.05, 1.0)), 5)
    body = lines([t_s(), *axes(a1), *axes(a2)], ["{:.2f}"] + ["{:.5f}"] * 6, ";")
    return Shape(text(["t;a1x;a1y;a1z;a2x;a2y;a2z"], body), FS, {
        "dut-1": Device({"t": "t", "ax": "a1x", "ay": "a1y", "az": "a1z"}, a1, keys={"delimiter": ";"}),
        "dut-2": Device({"t": "t", "ax": "a2x", "ay": "a2y", "az": "a2z"}, a2, keys={"delimiter": ";"})})


@shape
def two_triads_with_gyros() -> Shape:
    """``acc1_x…acc2_z`` (one in g, one in mg) and ``gyro1_x_dps…``: each device its own gyroscope."""
    a1, a2 = q(still(21) / G0, 6), q(still(22) / G0 * 1000, 2)
    w1, w2 = q(spin(21, peak=0.0), 3), q(spin(22, peak=0.0), 3)
    body = lines([t_s(), *axes(a1), *axes(a2), *axes(w1), *axes(w2)],
                 ["{:.2f}"] + ["{:.6f}"] * 3 + ["{:.2f}"] * 3 + ["{:.3f}"] * 6, ",")
    head = ["time," + ",".join(f"acc{k}_{a}" for k in (1, 2) for a in "xyz") + ","
            + ",".join(f"gyro{k}_{a}_dps" for k in (1, 2) for a in "xyz")]

    def cols(k: int) -> dict[str, str | int]:
        return {"t": "time", **{f"a{a}": f"acc{k}_{a}" for a in "xyz"},
                **{f"g{a}": f"gyro{k}_{a}_dps" for a in "xyz"}}

    return Shape(text(head, body), FS, {
        "dut-1": Device(cols(1), a1 * G0, np.radians(w1), {"acc_unit": "g", "gyro_unit": "deg/s"}),
        "dut-2": Device(cols(2), a2 * G0 / 1000, np.radians(w2), {"acc_unit": "mg", "gyro_unit": "deg/s"})})


@shape
def two_triads_headerless() -> Shape:
    """No names, time then six values in g: both triads have the norm of 1 g, quietly, so two
    accelerometers."""
    a1, a2 = q(still(23) / G0, 6), q(still(24, up=(0.0, 1.0, 0.0)) / G0, 6)
    body = lines([t_s(), *axes(a1), *axes(a2)], ["{:.2f}"] + ["{:.6f}"] * 6, " ")
    return Shape(text([], body), FS, {
        "dut-1": Device({"t": 0, "ax": 1, "ay": 2, "az": 3}, a1 * G0, keys={"acc_unit": "g"}),
        "dut-2": Device({"t": 0, "ax": 4, "ay": 5, "az": 6}, a2 * G0, keys={"acc_unit": "g"})},
                 said=("(their mean at rest has the norm of 1 g in g)",))


# --------------------------------------------------------------------------- apps and exports


@shape
def phyphox_csv() -> Shape:
    """phyphox's comma export: quoted names with units, an extra absolute value."""
    acc = q(still(25), 6)
    absolute = np.linalg.norm(acc, axis=1)
    body = lines([jittered(25, spread=0.05), *axes(acc), absolute], ["{:.9E}"] * 5, ",")
    head = ['"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)","Acceleration z (m/s^2)",'
            '"Absolute acceleration (m/s^2)"']
    cols = {"t": "Time (s)", "ax": "Acceleration x (m/s^2)", "ay": "Acceleration y (m/s^2)",
            "az": "Acceleration z (m/s^2)"}
    return Shape(text(head, body), FS, {"dut": Device(cols, acc)}, rate_tol=0.01)


@shape
def phyphox_excel() -> Shape:
    """phyphox's "semicolon, decimal comma" export, resaved by Excel: BOM and CRLF."""
    acc = q(still(26), 6)
    body = comma(lines([jittered(26, spread=0.05), *axes(acc)], ["{:.9E}"] * 4, ";"))
    head = ['"Time (s)";"Acceleration x (m/s^2)";"Acceleration y (m/s^2)";"Acceleration z (m/s^2)"']
    cols = {"t": "Time (s)", "ax": "Acceleration x (m/s^2)", "ay": "Acceleration y (m/s^2)",
            "az": "Acceleration z (m/s^2)"}
    return Shape(text(head, body, "\r\n", bom=True), FS, {"dut": Device(cols, acc, keys={"delimiter": ";"})},
                 rate_tol=0.01, said=("decimal_comma: true",))


@shape
def physics_toolbox_gforce() -> Shape:
    """Physics Toolbox's g-force meter: ``time,gFx,gFy,gFz,TgF`` in g, a phone's clock."""
    g = q(still(27) / G0, 4)
    total = np.linalg.norm(g, axis=1)
    body = lines([q(jittered(27), 3), *axes(g), total], ["{:.3f}"] + ["{:.4f}"] * 4, ",")
    return Shape(text(["time,gFx,gFy,gFz,TgF"], body), FS,
                 {"dut": Device({"t": "time", "ax": "gFx", "ay": "gFy", "az": "gFz"}, g * G0,
                                keys={"acc_unit": "g"})}, rate_tol=0.01)


@shape
def physics_toolbox_accelerometer() -> Shape:
    """Physics Toolbox's accelerometer: ``ax (m/s^2)`` and a total ``aT``."""
    acc = q(still(28), 4)
    body = lines([q(jittered(28), 3), *axes(acc), np.linalg.norm(acc, axis=1)], ["{:.3f}"] + ["{:.4f}"] * 4,
                 ",")
    head = ["time,ax (m/s^2),ay (m/s^2),az (m/s^2),aT (m/s^2)"]
    cols = {"t": "time", "ax": "ax (m/s^2)", "ay": "ay (m/s^2)", "az": "az (m/s^2)"}
    return Shape(text(head, body), FS, {"dut": Device(cols, acc)}, rate_tol=0.01)


@shape
def sensor_logger_android() -> Shape:
    """Sensor Logger (Android): epoch ns, seconds elapsed, then ``z,y,x``."""
    acc = q(still(29), 6)
    ns = EPOCH_NS + np.arange(N, dtype=np.int64) * 10_000_000
    body = lines([ns, t_s(), acc[:, 2], acc[:, 1], acc[:, 0]], ["{:d}", "{:.3f}"] + ["{:.6f}"] * 3, ",")
    return Shape(text(["time,seconds_elapsed,z,y,x"], body), FS,
                 {"dut": Device({"t": "time", "ax": "x", "ay": "y", "az": "z"}, acc,
                                keys={"time_unit": "ns"})})


@shape
def sensorlog_ios() -> Shape:
    """SensorLog (iOS): a text time, one time column per sensor, g and rad/s in the names, and
    gravity-free ``motionUserAcceleration`` beside the accelerometer's."""
    g, w = q(still(30) / G0, 6), q(np.radians(spin(30, peak=0.0)), 6)
    user = q(np.random.default_rng(30).normal(0, 0.002, (N, 3)), 6)
    texts = np.array([f"2025-03-14 10:22:{31 + i / 100:06.3f} +0000" for i in range(N)])
    boot = 5432.1 + t_s()
    body = lines([texts, np.arange(N), boot, *axes(g), boot + 0.004, *axes(w), *axes(user)],
                 ["{}", "{:d}", "{:.6f}"] + ["{:.6f}"] * 3 + ["{:.6f}"] * 7, ",")
    head = ["loggingTime(txt),loggingSample(N),accelerometerTimestamp_sinceReboot(s),"
            "accelerometerAccelerationX(G),accelerometerAccelerationY(G),accelerometerAccelerationZ(G),"
            "gyroTimestamp_sinceReboot(s),gyroRotationX(rad/s),gyroRotationY(rad/s),gyroRotationZ(rad/s),"
            "motionUserAccelerationX(G),motionUserAccelerationY(G),motionUserAccelerationZ(G)"]
    cols = {"t": "accelerometerTimestamp_sinceReboot(s)", "ax": "accelerometerAccelerationX(G)",
            "ay": "accelerometerAccelerationY(G)", "az": "accelerometerAccelerationZ(G)",
            "gx": "gyroRotationX(rad/s)", "gy": "gyroRotationY(rad/s)", "gz": "gyroRotationZ(rad/s)"}
    return Shape(text(head, body), FS, {"dut": Device(cols, g * G0, w, {"acc_unit": "g"})},
                 said=("sharing 'accelerometer' with the acceleration columns",))


@shape
def euroc_kalibr() -> Shape:
    """EuRoC / Kalibr IMU csv: a commented column line, ns stamps, gyroscope first, units in the
    names (``[rad s^-1]``, ``[m s^-2]``) telling the triads apart, 200 Hz."""
    n = N
    acc, w = q(still(31, up=(0.93, 0.02, -0.35)), 6), q(np.radians(spin(31, peak=0.0)), 6)
    ns = 1_403_636_579_758_555_392 + np.arange(n, dtype=np.int64) * 5_000_000
    body = lines([ns, *axes(w), *axes(acc)], ["{:d}"] + ["{:.6f}"] * 6, ",")
    head = ["#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
            "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]"]
    cols = {"t": "#timestamp [ns]", "ax": "a_RS_S_x [m s^-2]", "ay": "a_RS_S_y [m s^-2]",
            "az": "a_RS_S_z [m s^-2]", "gx": "w_RS_S_x [rad s^-1]", "gy": "w_RS_S_y [rad s^-1]",
            "gz": "w_RS_S_z [rad s^-1]"}
    return Shape(text(head, body), 200.0, {"dut": Device(cols, acc, w, {"time_unit": "ns"})})


@shape
def german_decimal_comma() -> Shape:
    """``Zeit (s);Beschl. X (g)…`` with decimal commas."""
    g = q(still(32) / G0, 6)
    body = comma(lines([t_s(), *axes(g)], ["{:.3f}"] + ["{:.6f}"] * 3, ";"))
    cols = {"t": "Zeit (s)", "ax": "Beschl. X (g)", "ay": "Beschl. Y (g)", "az": "Beschl. Z (g)"}
    return Shape(text(["Zeit (s);Beschl. X (g);Beschl. Y (g);Beschl. Z (g)"], body), FS,
                 {"dut": Device(cols, g * G0, keys={"acc_unit": "g"})})


@shape
def title_tab_milliseconds() -> Shape:
    """A title line, then tab-separated ``Time [ms]`` and ``Acc X [m/s^2]``."""
    acc = q(still(33), 5)
    body = lines([t_s() * 1000, *axes(acc)], ["{:.1f}"] + ["{:.5f}"] * 3, "\t")
    head = ["Sensor log 2025-03-14", "Time [ms]\tAcc X [m/s^2]\tAcc Y [m/s^2]\tAcc Z [m/s^2]"]
    cols = {"t": "Time [ms]", "ax": "Acc X [m/s^2]", "ay": "Acc Y [m/s^2]", "az": "Acc Z [m/s^2]"}
    return Shape(text(head, body), FS, {"dut": Device(cols, acc, keys={"skip_rows": 1, "time_unit": "ms"})})


@shape
def rate_preamble_trailing_comma() -> Shape:
    """``Fs,100``, names without a time column, a comma after every value."""
    g = q(still(34) / G0, 6)
    body = [line + "," for line in lines(axes(g), ["{:.6f}"] * 3, ",")]
    return Shape(text(["Fs,100", "ax,ay,az,"], body), FS,
                 {"dut": Device({"ax": "ax", "ay": "ay", "az": "az"}, g * G0,
                                keys={"sample_rate_hz": 100.0, "skip_rows": 1})})


# --------------------------------------------------------------------------- serial prints


@shape
def arduino_mpu6050_banner() -> Shape:
    """An Arduino sketch's serial print: banner lines, then ``millis()`` and raw counts (16384
    per g) separated by tabs, one line garbled by the link."""
    counts = np.rint(still(35) / G0 * 16384)
    body = lines([np.arange(N) * 10 + 1234, *axes(counts)], ["{:d}"] + ["{:.0f}"] * 3, "\t")
    keep = np.ones(N, dtype=bool)
    keep[1700] = False
    body[1700] = body[1700][:9]  # truncated by the serial link
    head = ["Initializing I2C devices...", "Testing device connections...", "MPU6050 connection successful"]
    return Shape(text(head, body), FS, {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3},
                                                      counts[keep] / 16384 * G0,
                                                      keys={"acc_unit": "counts", "lsb_per_g": 16384.0,
                                                            "time_unit": "ms", "skip_rows": 3,
                                                            "header": False})})


@shape
def arduino_stated_rate() -> Shape:
    """A banner stating the rate, then comma-separated counts (256 per g) and no time."""
    counts = np.rint(still(36) / G0 * 256)
    body = lines(axes(counts), ["{:.0f}"] * 3, ",")
    return Shape(text(["ADXL345 test", "Sample rate: 100 Hz"], body), FS,
                 {"dut": Device({"ax": 0, "ay": 1, "az": 2}, counts / 256 * G0,
                                keys={"sample_rate_hz": 100.0, "lsb_per_g": 256.0})})


@shape
def imu_tk_whitespace() -> Shape:
    """imu_tk's files: blank-separated scientific notation, seconds, then ax ay az gx gy gz, the
    board turned through six faces; the gyroscope's rad/s cannot be told from °/s by values below
    20, so it is left out with a note."""
    acc, w = poses(37)
    acc, w = q(acc, 6), q(w, 6)
    body = lines([t_s(), *axes(acc), *axes(w)], ["{:.7e}"] + ["{:.7e}"] * 6, "   ")
    return Shape(text([], [" " + line for line in body]), FS,
                 {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3}, acc, keys={"delimiter": "whitespace"})},
                 said=("give --gyro-unit rad/s or deg/s to map them",))


@shape
def gyro_first_headerless() -> Shape:
    """No names, angular rate (°/s, with a turn) before the acceleration: the values tell the
    triads apart."""
    acc, w = q(still(38), 5), q(spin(38), 3)
    body = lines([t_s(), *axes(w), *axes(acc)], ["{:.2f}"] + ["{:.3f}"] * 3 + ["{:.5f}"] * 3, " ")
    return Shape(text([], body), FS, {"dut": Device({"t": 0, "ax": 4, "ay": 5, "az": 6, "gx": 1, "gy": 2,
                                                     "gz": 3}, acc, np.radians(w), {"gyro_unit": "deg/s"})})


# --------------------------------------------------------------------------- what init cannot know


@shape
def arduino_unknown_lsb() -> Shape:
    """Signed counts of a scale init cannot know (330 per g): stop, name ``--lsb-per-g``."""
    counts = np.rint(still(39) / G0 * 330)
    body = lines([np.arange(N) * 10, *axes(counts)], ["{:d}"] + ["{:.0f}"] * 3, " ")
    return Shape(text(["# accel test"], body), FS,
                 {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3}, counts / 330 * G0,
                                keys={"acc_unit": "counts", "lsb_per_g": 330.0})},
                 flags=("--lsb-per-g", "330"),
                 refusal="‖mean‖ = 334.09 at rest (the quietest 100 samples, rows 1701–1800; median ‖f‖ "
                         "334.01): integers, so raw counts, but neither a power of two nor 1000 (mg): the "
                         "counts per g are unknown: give --lsb-per-g N")


@shape
def analog_adxl335() -> Shape:
    """``analogRead`` of an analog accelerometer: 10-bit, zero near mid-scale, 102.3 counts per g."""
    counts = np.rint(still(40) / G0 * 102.3) + 512
    body = lines([np.arange(N) * 10, *axes(counts)], ["{:d}"] + ["{:.0f}"] * 3, ",")
    return Shape(text([], body), FS, {"dut": Device({"t": 0, "ax": 1, "ay": 2, "az": 3},
                                                    (counts - 512) / 102.3 * G0,
                                                    keys={"lsb_per_g": 102.3, "zero_counts": 512.0})},
                 flags=("--unit", "counts", "--lsb-per-g", "102.3", "--zero-counts", "512"),
                 refusal="unsigned counts around mid-scale 512 in every axis (the quietest 100 samples, rows "
                         "2801–2900: means 513, 511, 616); ‖mean − 512‖ = 103.67 is no power of two, so the "
                         "zero and the counts per g are unknown: give --unit counts --lsb-per-g N "
                         "--zero-counts Z")


@shape
def no_time_no_rate() -> Shape:
    """Three values in g per line, nothing else: the rate must be given."""
    g = q(still(41) / G0, 5)
    body = lines(axes(g), ["{:.5f}"] * 3, ",")
    return Shape(text([], body), 50.0, {"dut": Device({"ax": 0, "ay": 1, "az": 2}, g * G0,
                                                      keys={"sample_rate_hz": 50.0})},
                 flags=("--rate", "50"),
                 refusal="no time column and no sample rate in the file: give --rate HZ")


@shape
def text_date_time() -> Shape:
    """A logger writing date and time as text (the readers take numbers only): the rate must be
    given."""
    g = q(still(42) / G0, 5)
    stamps = [f"2025-03-14,10:{22 + i // 6000:02d}:{(i % 6000) / 100:05.2f}" for i in range(N)]
    body = [f"{s},{line}" for s, line in zip(stamps, lines(axes(g), ["{:.5f}"] * 3, ","), strict=True)]
    return Shape(text(["Date,Time,X,Y,Z"], body), FS,
                 {"dut": Device({"ax": "X", "ay": "Y", "az": "Z"}, g * G0, keys={"sample_rate_hz": 100.0})},
                 flags=("--rate", "100"),
                 refusal="no time column and no sample rate in the file: give --rate HZ")


@shape
def sample_index_no_rate() -> Shape:
    """A sample counter instead of time stamps: the rate must be given."""
    g = q(still(43) / G0, 6)
    body = lines([np.arange(N), *axes(g)], ["{:d}"] + ["{:.6f}"] * 3, ",")
    return Shape(text(["sample,ax,ay,az"], body), 102.4,
                 {"dut": Device({"t": "sample", "ax": "ax", "ay": "ay", "az": "az"}, g * G0,
                                keys={"time_unit": "samples", "sample_rate_hz": 102.4})},
                 flags=("--rate", "102.4"),
                 refusal="'sample' is a sample index and the file states no rate: give --rate HZ")


@shape
def arduino_mpu6050_raw_example() -> Shape:
    """The MPU6050 library's raw example: ``a/g:`` then six counts, tab-separated, no time."""
    counts = np.rint(still(44) / G0 * 16384)
    w = np.rint(np.random.default_rng(44).normal(0, 20, (N, 3)) + [-120, 50, 30])
    body = ["a/g:\t" + line for line in lines([*axes(counts), *axes(w)], ["{:.0f}"] * 6, "\t")]
    return Shape(text(["Initializing I2C devices...", "MPU6050 connection successful"], body), FS,
                 {"dut": Device({"ax": 1, "ay": 2, "az": 3}, counts / 16384 * G0,
                                keys={"lsb_per_g": 16384.0, "sample_rate_hz": 100.0})},
                 flags=("--rate", "100"),
                 refusal="no time column and no sample rate in the file: give --rate HZ")


@shape
def linear_acceleration_only() -> Shape:
    """phyphox's "linear acceleration" (gravity removed): no specific force to label."""
    lin = q(np.random.default_rng(45).normal(0, 0.02, (N, 3)), 6)
    body = lines([t_s(), *axes(lin)], ["{:.9E}"] * 4, ",")
    head = ['"Time (s)","Linear Acceleration x (m/s^2)","Linear Acceleration y (m/s^2)",'
            '"Linear Acceleration z (m/s^2)"']
    return Shape(text(head, body), FS, {}, refusal="only gravity-free linear acceleration ('Linear "
                 "Acceleration x (m/s^2)', 'Linear Acceleration y (m/s^2)', 'Linear Acceleration z "
                 "(m/s^2)'), "
                 "not the specific force labelling needs: give --columns t=NAME,ax=NAME,ay=NAME,az=NAME")


# --------------------------------------------------------------------------- the checks

@functools.cache
def built(name: str) -> Shape:
    """The shape ``name``, written once per test session."""
    return SHAPES[name]()


def unaided() -> list[str]:
    """Shapes init must decide with no flag at all."""
    return sorted(k for k in SHAPES if not built(k).flags and built(k).refusal is None)


def _folder(tmp_path: Path, name: str, content: bytes) -> Path:
    folder = tmp_path / "lab-2026" / "pc-01"
    folder.mkdir(parents=True)
    (folder / f"{name}.csv").write_bytes(content)
    return folder


def _verify(folder: Path, s: Shape) -> None:
    """The manifest names the right devices and columns, and reads the true acceleration at the
    true rate."""
    m = load_manifest(folder)
    assert sorted(m.devices) == sorted(s.devices)
    (rec_spec,) = m.recordings
    for dev, want in s.devices.items():
        spec = m.devices[dev]
        assert spec.csv is not None and spec.csv.columns == want.columns, (dev, spec.to_dict())
        entry = spec.to_dict()
        assert {k: entry.get(k, {"header": True, "skip_rows": 0}.get(k)) for k in want.keys} == want.keys
        rec = read_device_file(m.file_path(rec_spec, dev), spec)
        assert rec.acc.shape == want.acc.shape, dev
        np.testing.assert_allclose(rec.acc, want.acc, rtol=0, atol=1e-8)
        assert rec.fs_hz == pytest.approx(s.rate_hz, rel=s.rate_tol)
        gyro = rec.gyro()
        if want.gyro is None:
            assert gyro is None, dev
        else:
            assert gyro is not None, dev
            np.testing.assert_allclose(gyro, want.gyro, rtol=0, atol=1e-8)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SHAPES))
def test_init_decides_each_shape(tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]) -> None:
    s = built(name)
    folder = _folder(tmp_path, name, s.text)
    path = folder / f"{name}.csv"
    if s.refusal is not None:
        assert main(["init", str(folder)]) == 2
        err = [line for line in capsys.readouterr().err.splitlines() if "warning" not in line]
        assert err == [f"ofbe-session: error: {path}: {s.refusal}"]
        assert not (folder / "session.yaml").exists()
        if not s.flags:
            return
    assert main(["init", str(folder), *s.flags]) == 0
    captured = capsys.readouterr()
    for said in s.said:
        assert said in captured.out, captured.out
    for warned in s.warned:
        assert warned in captured.err, captured.err
    _verify(folder, s)


def test_the_corpus_is_decided_unaided() -> None:
    """The score (the issue asks for at least 25 shapes decided unaided): 35 of the 43 shapes need
    no flag, each passing the test above; one is given ``--unit counts`` to test that path; the
    seven others stop with the one flag that settles them (six of them then decide correctly)."""
    refused = [k for k in SHAPES if built(k).refusal is not None]
    assert (len(SHAPES), len(unaided()), len(refused)) == (43, 35, 7)


def test_init_prints_the_rate_check_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Host-clock stamps with gaps: the median step and the mean rate differ; init prints check's."""
    s = built("host-clock")
    folder = _folder(tmp_path, "host", s.text)
    assert main(["init", str(folder)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.strip().startswith("rate: "))
    rate = line.split("rate: ")[1].split(" Hz")[0]
    assert "the mean rate, as check reports it: (2998 samples − 1 + 2 missing in gaps) / " in line
    assert "median step 0.01" in line
    main(["check", str(folder)])
    check = capsys.readouterr().out
    assert f"csv: 2998 rows, {rate} Hz, " in check


@pytest.mark.parametrize(("session", "power_cycle"), [
    ("imu9", None), ("fxos8700", None), ("mpu9255-rest", None), ("session-07", None), ("rot-pc07", 7),
    ("pc3", 3), ("power_cycle_3", 3), ("mpu9255-pc-003", 3), ("cycle3", 3), ("imu9_PowerCycle12", 12),
    ("bicycle4", None)])
def test_power_cycle_only_from_an_explicit_pattern(tmp_path: Path, session: str, power_cycle: int | None,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "lab" / session
    folder.mkdir(parents=True)
    (folder / "rec.csv").write_bytes(built("bracket-index").text)
    assert main(["init", str(folder)]) == 0
    captured = capsys.readouterr()
    assert load_manifest(folder).power_cycle == (power_cycle or 1)
    line = next(x for x in captured.out.splitlines() if x.startswith("  power_cycle: "))
    if power_cycle is None:
        assert line == ("  power_cycle: 1 (no power-cycle pattern (pc3, pc-003, power_cycle_3, cycle3) in "
                        f"the session id {session!r}; its digits are not taken (often a model number): 1 — "
                        "give --power-cycle N, unique per device within the campaign)")
        assert "ofbe-session: warning: power_cycle 1: no power-cycle pattern" in captured.err
    else:
        assert line.startswith(f"  power_cycle: {power_cycle} (") and f"in the session id {session!r}" in line
        assert "warning: power_cycle" not in captured.err
