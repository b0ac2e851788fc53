"""What the classical estimators share: constants, window means, nearest axes, input checks.

The estimators themselves, one module per family:
:mod:`~ofbe_model.estimators.physics` (level-mean, ls-trf, won2009),
:mod:`~ofbe_model.estimators.priors` (prior-mean, gravity-prior),
:mod:`~ofbe_model.estimators.oracle` (oracle). Registered names (methods.md §Estimators, docs/estimators.md):

- ``level-mean`` (:class:`LevelMean`): window mean − g_local·(nearest signed axis);
- ``ls-trf`` (:class:`LSTRF`): min over b of Σ(‖f_i − b‖ − g)² by scipy's TRF, in three
  honest variants (``as-written``, ``bounded``, ``min-norm``);
- ``won2009`` (:class:`Won2009`): iterative linear solve of 2·u_i·δ = ‖u_i‖² − g²;
- ``prior-mean`` (:class:`PriorMean`): the training-label mean per device;
- ``gravity-prior`` (:class:`GravityPrior`): along-gravity component from the norm of the
  window mean, tangential components from a Gaussian prior learned on the labels;
- ``oracle`` (:class:`Oracle`): the posterior mean under the simulator's true device
  distributions (simulated data only; the one estimator that reads truth files).

Conventions: a window is (T, 3) specific force in m/s², sensor frame; a batch is (N, T, 3);
biases and standard deviations are (N, 3) m/s². ``g`` is the local gravity magnitude from
``meta["g_local"]``, m/s². ``h`` is the unit direction of the window's mean specific force
(the measured "up"). A single stationary window determines only the bias component along
``h``; the maths of that, and what each estimator does about it, is in docs/estimators.md.

The maths lives in small pure functions (:func:`window_means`, :func:`nearest_axes`,
:func:`ls_trf_solve`, :func:`won2009_solve`, :func:`condition_on_norm`,
:func:`mixture_moments`, :func:`gaussian_prior`, :func:`floor_cov`, :func:`direction_prior`,
:func:`read_truth_devices`); the classes (in the family modules) wire them to the
:class:`~ofbe_model.estimators.base.Estimator` interface.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.io.gravity import G0
from ofbe_model.estimators.base import Estimator, EstimatorError

MG = G0 * 1e-3
"""One milli-g in m/s² (a unit conversion with standard gravity g0 = 9.80665 m/s²)."""

LS_VARIANTS = ("as-written", "bounded", "min-norm")
"""Variants of ``ls-trf`` (docs/estimators.md)."""

GRAVITY_PRIOR_FORMAT = "ofbe-gravity-prior/1"
"""``format`` field of a saved :class:`GravityPrior` (JSON)."""

TRUTH_FORMAT = "ofbe-truth/1"
"""``format`` field of the simulator's truth files, read by :class:`Oracle` only."""

GN_ITERATIONS = 6
"""Gauss–Newton relinearisations of the norm observation in :func:`condition_on_norm`. The
first linearises at the prior mean; the linearisation error after it is ‖Δb_⊥‖²/(2g) for a
tangential correction Δb_⊥ (0.013 mg for 5 mg), and each further pass shrinks the remaining
error by about ‖Δb_⊥‖/g (5e-3 for 5 mg); six passes reach float64 round-off in practice."""


# ----------------------------------------------------------------------------- small helpers


def window_means(windows: np.ndarray) -> np.ndarray:
    """Mean specific force of each window, accumulated in float64.

    Parameters
    ----------
    windows
        (N, T, 3) m/s² (float32 or float64).

    Returns
    -------
    ndarray, shape (N, 3)
        m/s².
    """
    return np.mean(np.asarray(windows), axis=1, dtype=np.float64)


def nearest_axes(means: np.ndarray) -> np.ndarray:
    """Signed sensor axis closest to each mean reading (vectorised
    :func:`ofbe_data.labelling.orientation.nearest_axis`).

    Parameters
    ----------
    means
        (N, 3) mean specific force, any unit.

    Returns
    -------
    ndarray, shape (N, 3)
        ``±e_k`` with k = argmax |m_k| and the sign of m_k (+ for m_k = 0).
    """
    m = np.asarray(means, dtype=np.float64)
    k = np.argmax(np.abs(m), axis=1)
    rows = np.arange(m.shape[0])
    out = np.zeros_like(m)
    out[rows, k] = np.where(m[rows, k] >= 0.0, 1.0, -1.0)
    return out


def unit_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-wise unit vectors and norms of (N, 3) vectors."""
    n = np.linalg.norm(v, axis=1)
    return v / n[:, None], n


def g_local_column(meta: pd.DataFrame) -> np.ndarray:
    """``meta["g_local"]`` as float64, checked finite and positive, m/s²."""
    try:
        g = meta["g_local"].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise EstimatorError(f"meta: expected numeric g_local (m/s²), found {exc}") from None
    bad = ~(np.isfinite(g) & (g > 0.0))
    if bad.any():
        raise EstimatorError(f"meta: expected finite positive g_local (m/s²), found {g[bad][0]!r}")
    return g


def device_column(meta: pd.DataFrame) -> np.ndarray:
    """``meta["device"]`` as an array of str."""
    return meta["device"].astype(str).to_numpy()


def as_float_tuple(value: Any, n: int, what: str) -> np.ndarray:
    """A parameter that must be n finite numbers, as a float64 array."""
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise EstimatorError(f"{what}: expected {n} numbers, found {value!r}") from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise EstimatorError(f"{what}: expected {n} finite numbers, found {value!r}")
    return arr


def is_int(value: Any) -> bool:
    """Whether value is an integer (numpy integers included, bool excluded)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_real(value: Any) -> bool:
    """Whether value is a real number (numpy floats included, bool excluded)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_fitted(est: Estimator, attr: str) -> None:
    if not hasattr(est, attr):
        raise EstimatorError(f"{est.name}: expected a fitted estimator (call fit first), found it unfitted")


