"""Time of :func:`ofbe_data.labelling.multiposition.estimate_tau2` on a multi-position fit of many
poses (issue 36: 6 of the 16 s of ``ofbe-session check`` on a 20.7-hour wrist file, 1949 poses, went
to one eigen-decomposition), and how far its fast path is from the eigen-decomposition.

The problem has the shape :func:`~ofbe_data.labelling.multiposition._errors.norm_fit_errors` gives it: K
poses at random orientations, one in 50 sharing a cluster with the previous pose (within a
degree), the cluster structure (g_k·g_l inside a cluster), each pose's white noise, and the
projector off a random (K, 9) Jacobian's column space. Each variant runs on one thread (CPU
seconds, so that other work on the machine does not count):

- ``eigen``: ``exact_spectrum=True``, the eigen-decomposition (the code before this change);
- ``fast``: the projector's basis given (what ``norm_fit_errors`` does): one LDLᵀ factorisation
  counts the eigenvalues below ``VISIBLE``, and no (K, K) product forms V or Q_W;
- ``fast, no basis``: two factorisations decide.

Run: ``python benchmarks/tau2_speed.py [--poses 1949] [--repeat 3]``. Nothing is asserted: this is a
measurement (the tests in ``tests/ofbe_data/labelling/test_pose_errors.py`` check the numbers).

Measured on a 2-core AMD EPYC shared with other jobs, 1949 poses (CPU s, one run): eigen 4.8,
fast 0.99, fast without basis 2.1; τ² and its degrees of freedom within 6e-16 relative of the
eigen-decomposition's (1e-11 with the white noise estimated too: two nearly equal terms). On the
arguments ``check`` passes for the 20.7-hour file of ``benchmarks/memory_init_label.py``: 4.6 s →
0.75 s, within 3e-15 relative (2e-12).
"""

from __future__ import annotations

import argparse
import os
import sys

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # before NumPy loads its BLAS: CPU time of one thread

import time  # noqa: E402

import numpy as np  # noqa: E402

from ofbe_data.labelling.multiposition import column_space_basis, estimate_tau2, pose_clusters  # noqa: E402


def problem(poses: int, seed: int = 36) -> dict[str, np.ndarray]:
    """Arguments of ``estimate_tau2`` with the structure ``norm_fit_errors`` gives them.

    Returns
    -------
    dict
        ``y`` (K,) m/s², ``q_map`` (K, K), ``known`` (K, K) (m/s²)², ``cluster`` (K, K),
        ``basis`` (K, 9).
    """
    rng = np.random.default_rng(seed)
    means = rng.normal(size=(poses, 3))
    again = rng.random(poses) < 0.02  # a pose within a degree of the previous one
    again[0] = False
    means[again] = means[np.flatnonzero(again) - 1] + rng.normal(scale=0.01, size=(int(again.sum()), 3))
    means *= 9.81 / np.linalg.norm(means, axis=1, keepdims=True)
    clusters = pose_clusters(["rec"] * poses, means, tolerance_deg=1.0)
    grad = means / 9.81
    cluster = (grad @ grad.T) * (clusters[:, None] == clusters[None, :])
    known = np.diag(np.full(poses, (2e-3 * 9.81) ** 2 / 600.0) * rng.uniform(0.5, 2.0, poses))
    basis = column_space_basis(rng.normal(size=(poses, 9)))
    q_map = np.eye(poses) - basis @ basis.T
    errors = rng.normal(scale=3e-3, size=poses)
    return {"y": q_map @ errors, "q_map": q_map, "known": known, "cluster": cluster, "basis": basis}


def _cpu(fn: object, repeat: int) -> tuple[float, tuple[float, float]]:
    times, out = [], (0.0, 0.0)
    for _ in range(repeat):
        start = time.process_time()
        out = fn()  # type: ignore[operator]
        times.append(time.process_time() - start)
    return float(np.median(times)), out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--poses", type=int, default=1949, help="number of poses K")
    p.add_argument("--repeat", type=int, default=3, help="runs of each variant (the median is shown)")
    args = p.parse_args(argv)
    a = problem(args.poses)
    base = (a["y"], a["q_map"], a["known"], a["cluster"])
    for white_known in (True, False):
        ref_s, ref = _cpu(lambda wk=white_known: estimate_tau2(*base, wk, exact_spectrum=True), args.repeat)
        print(f"{args.poses} poses, white noise {'known' if white_known else 'estimated'}: "
              f"eigen {ref_s:.2f} s CPU, tau2 {ref[0]:.6e}, dof {ref[1]:.6g}", flush=True)
        for name, kwargs in (("fast", {"projector_basis": a["basis"]}), ("fast, no basis", {})):
            secs, got = _cpu(lambda kw=kwargs, wk=white_known: estimate_tau2(*base, wk, **kw), args.repeat)
            rel = max(abs(g - r) / abs(r) if r else abs(g) for g, r in zip(got, ref, strict=True))
            print(f"  {name:<15} {secs:.2f} s CPU ({ref_s / secs:.1f}× faster), largest relative "
                  f"difference {rel:.1e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
