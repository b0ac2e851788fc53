"""Writing a simulated session: the device files (with a noisy serial link's garbled lines), the
manifest and the truth JSON.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.precision import round_floats
from ofbe_data.io.formats.mscip_bin import write_mscip_bin
from ofbe_data.io.formats.mscip_csv import write_mscip_csv
from ofbe_data.io.formats.ofbe_logger import write_ofbe_logger
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import (
    write_manifest,
)
from ofbe_data.simulator.campaign import GARBLE_BYTES, TRUTH_DECIMALS, SessionData

# --------------------------------------------------------------------------- writing


def fixed(values: np.ndarray, decimals: int) -> np.ndarray:
    """``values`` rounded to ``decimals`` decimals as the vendor-style CSV writes them (same shape)."""
    return np.rint(np.asarray(values, dtype=np.float64) * 10.0**decimals) / 10.0**decimals


class Garbler:
    """Corrupts serial lines the way a noisy link does, and counts what it did.

    Three kinds, always detectable by the reader: a line cut before its last field, a
    non-numeric byte inside a field, and a line cut after its first field and run into
    the next one (two samples lost, one line). The first and last data lines are left
    intact so that the count of samples lost is exactly recoverable from gaps.

    Parameters
    ----------
    rate
        Probability that a data line is garbled.
    rng
        Random generator.
    """

    def __init__(self, rate: float, rng: np.random.Generator) -> None:
        self.rate = rate
        self.rng = rng
        self.lines = 0
        self.samples_lost = 0

    def __call__(self, lines: list[bytes]) -> list[bytes]:
        self.lines = self.samples_lost = 0
        n = len(lines)
        if n < 4 or self.rate == 0:
            return lines
        hits = np.flatnonzero(self.rng.random(n) < self.rate)
        hits = hits[(hits > 0) & (hits < n - 2)]
        out = list(lines)
        merged: set[int] = set()
        for i in hits:
            i = int(i)
            if i in merged or i - 1 in merged:
                continue
            line = out[i]
            kind = int(self.rng.integers(3))
            commas = [j for j, ch in enumerate(line) if ch == 44]
            if kind == 0:
                out[i] = line[: int(self.rng.integers(0, commas[-1] + 1))]
            elif kind == 1:
                j = int(self.rng.integers(len(line)))
                bad = GARBLE_BYTES[int(self.rng.integers(len(GARBLE_BYTES)))]
                out[i] = line[:j] + bad + line[j + 1:]
            else:
                out[i] = line[: int(self.rng.integers(commas[0] + 1, commas[-1] + 1))] + out[i + 1]
                merged.add(i)
                self.samples_lost += 1
            self.lines += 1
            self.samples_lost += 1
        return [line for j, line in enumerate(out) if j - 1 not in merged]


def write_session(data: SessionData, folder: Path, truth_path: Path, garble_rate: float,
                  seed_seq: np.random.SeedSequence) -> None:
    """Write a simulated session: manifest, device files and truth JSON.

    Parameters
    ----------
    data
        The simulated session.
    folder
        Session folder (created).
    truth_path
        Truth JSON file.
    garble_rate
        Probability of a garbled serial line.
    seed_seq
        Seed sequence for the garbling.
    """
    garbler = Garbler(garble_rate, np.random.default_rng(seed_seq))
    for rec in data.manifest.recordings:
        (folder / rec.id).mkdir(parents=True, exist_ok=True)
        for dev, rel in rec.files.items():
            path = folder / rel
            if (rec.id, dev) in data.dut_files:
                f = data.dut_files[(rec.id, dev)]
                write_ofbe_logger(path, f.t_us, f.counts, f.header, f.boot_lines, garbler)
                f.truth["garbled_lines"] = garbler.lines
                f.truth["samples_lost_to_garbling"] = garbler.samples_lost
                f.truth["lines_written"] = f.truth["samples_written"] - garbler.samples_lost \
                    + garbler.lines
            elif data.manifest.devices[dev].format == "mscip-bin":
                r = data.ref_files[rec.id]
                # the values the CSV would hold (its decimals), as float32 in the byte stream
                write_mscip_bin(path, fixed(r.t_s, 6), fixed(r.acc_g, 5) * G0, r.start_utc,
                                gyro=fixed(r.gyro_dps, 4), temperature=fixed(r.temperature_c, 1))
            else:
                r = data.ref_files[rec.id]
                write_mscip_csv(path, r.t_s, r.acc_g, r.gyro_dps, r.temperature_c,
                                serial=r.serial, rate_hz=r.rate_hz, start_utc=r.start_utc)
    write_manifest(data.manifest, folder / "session.yaml")
    truth = round_floats(data.truth, TRUTH_DECIMALS)
    write_bytes_atomic(truth_path, (json.dumps(truth, indent=1) + "\n").encode())
