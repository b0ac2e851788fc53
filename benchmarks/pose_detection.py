"""Pose detection in continuous multi-position recordings: speed and accuracy on synthetic truth.

Usage: python benchmarks/pose_detection.py [--repeat N] [--seeds N]

Builds the synthetic recordings of ``tests/ofbe_data/labelling/test_poses.py`` (K poses of 2–10 s, 1–4 s
of handling between them, ADXL345-like noise and quantisation, a known offset and scale) and
prints:

- the time ``find_poses`` takes per 10 minutes of 100 Hz data (a ~10-min recording of 70
  poses, best of ``--repeat`` runs), and ``detect_static`` for one threshold;
- for K = 6, 9, 18, 40 and 50, 100, 400 Hz, over ``--seeds`` recordings each (half of them
  starting with handling), with the hand's jolts and without (gentle handling): poses found /
  true, poses found exactly once, the mean and smallest coverage of each true still interval
  less its margins, the largest stretch of a pose outside its still interval, and the largest
  ratio of the offset error to the noise-derived tolerance of the tests (≤ 1 passes).

Nothing is asserted: this is a measurement.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' synthetic recordings

from ofbe_data.labelling.multiposition import (  # noqa: E402
    PoseParams,
    detect_static,
    find_poses,
    fit_poses,
)
from tests.ofbe_data.labelling.test_poses import (  # noqa: E402
    G,
    Synthetic,
    _offset_tolerance,
    synthetic_recording,
)


def time_detection(repeat: int) -> None:
    """Print find_poses' and detect_static's time per 10 minutes of 100 Hz data."""
    synth = synthetic_recording(70, 100.0, seed=1)
    minutes = synth.t.shape[0] / 100.0 / 60.0
    best, best_static = np.inf, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        det = find_poses(synth.t, synth.acc, 100.0, G)
        best = min(best, time.perf_counter() - t0)
        t0 = time.perf_counter()
        detect_static(synth.acc, 100.0, det.multiplier * det.noise_floor_var[0])
        best_static = min(best_static, time.perf_counter() - t0)
    print(f"recording: {minutes:.1f} min at 100 Hz, {len(det.poses[0])} poses found of 70 "
          f"({len(PoseParams().multipliers)} multipliers tried)")
    print(f"find_poses:    {best * 1e3 * 10.0 / minutes:8.1f} ms per 10 min of 100 Hz data")
    print(f"detect_static: {best_static * 1e3 * 10.0 / minutes:8.1f} ms per 10 min (one threshold)")


def accuracy(synth: Synthetic) -> dict[str, float]:
    """Detection accuracy of one recording against its truth."""
    det = find_poses(synth.t, synth.acc, synth.fs, G)
    margin = int(round(PoseParams().margin_s * synth.fs))
    once, coverage, outside, matched = 0, [], [0.0], []
    for a, b in synth.still:
        hits = [p for p in det.poses[0] if p.start < b and p.stop > a]
        if len(hits) != 1:
            continue
        p = hits[0]
        once += 1
        matched.append(p)
        coverage.append((min(p.stop, b - margin) - max(p.start, a + margin)) / (b - a - 2 * margin))
        outside.append(max(a - p.start, p.stop - b, 0) / synth.fs)
    k = synth.still.shape[0]
    ratio = np.nan
    if once == k:
        model = "scale-offset" if k >= 9 else "offset"
        fit = fit_poses(np.array([p.mean for p in matched]), G, model)
        ratio = float(np.max(np.abs(fit.offset - synth.offset) / _offset_tolerance(synth, matched, model)))
    return {"found": len(det.poses[0]), "true": k, "once": once, "coverage": float(np.mean(coverage)),
            "min_coverage": float(np.min(coverage)), "outside_s": max(outside), "offset_ratio": ratio}


def print_accuracy(seeds: int, jolts: bool) -> None:
    """Print the accuracy table for every K and rate."""
    print(f"\n{'with the hand' + chr(39) + 's jolts' if jolts else 'gentle handling (no jolts)'}, "
          f"{seeds} recordings per row")
    print(f"{'K':>3s} {'Hz':>4s} {'found/true':>11s} {'once':>9s} {'coverage':>9s} {'min cov':>8s} "
          f"{'outside (s)':>11s} {'offset err/tol':>14s}")
    for k in (6, 9, 18, 40):
        for fs in (50.0, 100.0, 400.0):
            rows = [accuracy(synthetic_recording(k, fs, seed=10_000 + 100 * s + k,
                                                 start_with_motion=bool(s % 2), jolts=jolts))
                    for s in range(seeds)]
            found, true = sum(r["found"] for r in rows), sum(r["true"] for r in rows)
            once = sum(r["once"] for r in rows)
            coverage = np.mean([r["coverage"] for r in rows])
            least = min(r["min_coverage"] for r in rows)
            outside = max(r["outside_s"] for r in rows)
            ratio = np.nanmax([r["offset_ratio"] for r in rows])
            print(f"{k:3d} {fs:4.0f} {found:5d}/{true:<5d} {once:4d}/{true:<4d} {coverage:9.3f} "
                  f"{least:8.3f} {outside:11.3f} {ratio:14.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args()
    time_detection(args.repeat)
    print_accuracy(args.seeds, jolts=True)
    print_accuracy(args.seeds, jolts=False)


if __name__ == "__main__":
    main()
