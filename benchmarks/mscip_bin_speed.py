"""Decode throughput of the vectorised ``mscip-bin`` decoder against a naive per-packet loop.

Usage: python benchmarks/mscip_bin_speed.py [--samples 1000000] [--naive-samples 50000] [--repeat 3]

Builds a stream of ``--samples`` IMU output packets (accelerometer, gyroscope, temperature and
time sub-packets: 54 bytes a sample, 200 Hz) with the toolkit's writer, then times
:func:`~ofbe_data.io.formats.mscip_bin.decode_mscip` (best of ``--repeat``) and the whole
:func:`~ofbe_data.io.formats.mscip_bin.read_mscip_bin` on a file. The naive decoder walks the
packets one at a time in Python (``bytes.find`` for the sync bytes, py-mscip's own
``compute_fletcher`` for the checksum, ``struct.unpack_from`` for the fields) on the first
``--naive-samples`` packets; its rate is per sample, so the ratio does not depend on that
subset. Prints; asserts nothing.
"""

from __future__ import annotations

import argparse
import struct
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ofbe_data.io.formats.mscip_bin import decode_mscip, encode_mscip, read_mscip_bin


def _fletcher(data: bytes) -> int:
    """MSCIP checksum, the way py-mscip computes it (per byte, modulo 256)."""
    c1 = c2 = 0
    for byte in data:
        c1 = (c1 + byte) & 0xFF
        c2 = (c2 + c1) & 0xFF
    return (c1 << 8) | c2


def _vendor_fletcher() -> Callable[[bytes], int]:
    try:
        from py_mscip.packets.cip import compute_fletcher
    except ImportError:  # py-mscip is a dev dependency
        return _fletcher
    return compute_fletcher  # type: ignore[no-any-return]


def naive_decode(buffer: bytes, fletcher: Callable[[bytes], int]) -> np.ndarray:
    """A per-packet Python decoder: (N, 3) accelerometer values of the valid IMU packets."""
    out: list[tuple[float, float, float]] = []
    pos, n = 0, len(buffer)
    while True:
        i = buffer.find(b"\xa5\xa5", pos)
        if i < 0 or i + 4 > n:
            break
        end = i + 4 + buffer[i + 3]
        if end + 2 > n:
            break
        if fletcher(buffer[i:end]) != (buffer[end] << 8 | buffer[end + 1]):
            pos = i + 1
            continue
        j = i + 4
        while j < end:
            code, length = buffer[j], buffer[j + 1]
            if code == 0x81 and length == 12 and buffer[i + 2] == 0xA2:
                out.append(struct.unpack_from(">3f", buffer, j + 2))
            j += 2 + length
        pos = end + 2
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def _best(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--naive-samples", type=int, default=50_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    n = args.samples
    rng = np.random.default_rng(0)
    t = np.arange(n) / 200.0
    acc = rng.normal(0.0, 0.01, (n, 3)) + [0.0, 0.0, 1.0]
    t0 = time.perf_counter()
    data = encode_mscip(t, acc, "2025-03-14T10:22:31.512Z", gyro=rng.normal(0.0, 0.01, (n, 3)),
                        temperature=np.full(n, 31.2))
    t_enc = time.perf_counter() - t0
    mb = len(data) / 1e6
    print(f"stream: {n} samples, {mb:.1f} MB ({len(data) // n} bytes a packet); encode {t_enc:.2f} s")
    stream = decode_mscip(data)
    assert stream.n == n
    t_vec = _best(lambda: decode_mscip(data), args.repeat)
    print(f"decode_mscip (vectorised): {t_vec:.3f} s  {mb / t_vec:8.1f} MB/s  {n / t_vec:12,.0f} samples/s")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "memsense.bin"
        path.write_bytes(data)
        t_read = _best(lambda: read_mscip_bin(path), args.repeat)
    print(f"read_mscip_bin (file → Recording): {t_read:.3f} s  {mb / t_read:8.1f} MB/s  "
          f"{n / t_read:12,.0f} samples/s")
    m = min(args.naive_samples, n)
    part = data[: m * (len(data) // n)]
    fletcher = _vendor_fletcher()
    t0 = time.perf_counter()
    naive = naive_decode(part, fletcher)
    t_naive = time.perf_counter() - t0
    assert np.array_equal(naive, stream.acc[:m])
    rate_naive = m / t_naive
    print(f"naive per-packet loop ({m} samples): {t_naive:.3f} s  {len(part) / 1e6 / t_naive:8.2f} MB/s  "
          f"{rate_naive:12,.0f} samples/s")
    print(f"speed-up, vectorised / naive: {n / t_vec / rate_naive:.0f}x "
          f"(whole read: {n / t_read / rate_naive:.0f}x)")


if __name__ == "__main__":
    main()
