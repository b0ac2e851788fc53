"""Estimators that bring a learned prior: ``prior-mean`` (the training labels' mean per device)
and ``gravity-prior`` (the along-gravity part from the norm of the window mean, the tangential
part from a Gaussian prior, optionally linear in the measured up direction).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_model.estimators.base import Estimator, EstimatorError, check_inputs, register
from ofbe_model.estimators.common import (
    GN_ITERATIONS,
    GRAVITY_PRIOR_FORMAT,
    MG,
    check_fitted,
    device_column,
    g_local_column,
    is_int,
    is_real,
    unit_rows,
    window_means,
)
from ofbe_model.estimators.domain import TrainingDomain, domain_of

# ----------------------------------------------------------------------------- prior-mean


@register
class PriorMean(Estimator):
    """``prior-mean``: the mean training label of the window's device.

    What a regressor that ignores the signal can learn. Unseen devices get the mean over all
    training labels. :meth:`predict_std` is the per-device sample standard deviation of the
    labels (ddof = 1; the overall one for unseen devices and for devices with one label).

    Attributes
    ----------
    means_
        ``{device: (3,) m/s²}``.
    stds_
        ``{device: (3,) m/s²}``.
    overall_, overall_std_
        (3,) m/s² over all training labels.
    """

    name: ClassVar[str] = "prior-mean"
    order: ClassVar[int] = 40
    needs_fit: ClassVar[bool] = True

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> PriorMean:
        """Learn the per-device label means and standard deviations."""
        check_inputs(windows, meta, labels)
        y = np.asarray(labels, dtype=np.float64)
        if y.shape[0] == 0:
            raise EstimatorError("prior-mean: expected at least one training window, found none")
        dev = device_column(meta)
        self.overall_ = y.mean(axis=0)
        self.overall_std_ = y.std(axis=0, ddof=1) if y.shape[0] > 1 else np.zeros(3)
        self.means_ = {}
        self.stds_ = {}
        for d in sorted(set(dev)):
            yd = y[dev == d]
            self.means_[d] = yd.mean(axis=0)
            self.stds_[d] = yd.std(axis=0, ddof=1) if yd.shape[0] > 1 else self.overall_std_.copy()
        return self

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """The device's mean training label per window, (N, 3) m/s²."""
        check_inputs(windows, meta)
        check_fitted(self, "means_")
        return np.array([self.means_.get(d, self.overall_) for d in device_column(meta)]).reshape(-1, 3)

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """The device's training-label standard deviation per window, (N, 3) m/s²."""
        check_inputs(windows, meta)
        check_fitted(self, "stds_")
        return np.array([self.stds_.get(d, self.overall_std_) for d in device_column(meta)]).reshape(-1, 3)


# ----------------------------------------------------------------------------- gravity-prior maths


def gaussian_prior(labels: np.ndarray, min_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of labels, with every eigenvalue floored at min_std².

    Parameters
    ----------
    labels
        (n, 3) m/s², n ≥ 1.
    min_std
        Smallest standard deviation along any direction, m/s² (> 0 keeps the covariance
        positive definite; with one label the covariance is min_std²·I).

    Returns
    -------
    mean
        (3,) m/s².
    cov
        (3, 3) (m/s²)², symmetric positive definite.
    """
    y = np.asarray(labels, dtype=np.float64)
    mean = y.mean(axis=0)
    cov = np.cov(y, rowvar=False, ddof=1) if y.shape[0] > 1 else np.zeros((3, 3))
    return mean, floor_cov(cov, min_std)


def floor_cov(cov: np.ndarray, min_std: float) -> np.ndarray:
    """A symmetric 3×3 covariance with every eigenvalue raised to at least min_std².

    Parameters
    ----------
    cov
        (3, 3), (m/s²)².
    min_std
        m/s².

    Returns
    -------
    ndarray, shape (3, 3)
        Symmetric positive definite (for min_std > 0).
    """
    vals, vecs = np.linalg.eigh(0.5 * (np.asarray(cov, dtype=np.float64) + np.asarray(cov).T))
    out = (vecs * np.maximum(vals, min_std * min_std)) @ vecs.T
    return 0.5 * (out + out.T)


def direction_prior(labels: np.ndarray, h: np.ndarray, min_std: float, ridge: float,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A Gaussian prior whose mean is linear in the window's up direction h.

    μ(h) = ȳ + C·(h − h̄), C = Y_cᵀH_c (H_cᵀH_c + ridge·n·I)⁻¹ by ridge regression of the
    centred labels on the centred directions; the covariance is that of the residuals
    (n − 4 degrees of freedom), floored like :func:`floor_cov`. On a rotated campaign C
    learns the apparent bias's orientation-dependent part (A − I)·g; directions that the
    training windows do not span stay at C = 0 through the ridge.

    Parameters
    ----------
    labels
        (n, 3) m/s².
    h
        (n, 3) unit up directions of the training windows.
    min_std
        Floor of the residual standard deviation, m/s².
    ridge
        Ridge relative to n (dimensionless, > 0).

    Returns
    -------
    mean
        (3,) ȳ, m/s².
    slope
        (3, 3) C, m/s² per unit of h.
    centre
        (3,) h̄.
    cov
        (3, 3) residual covariance, (m/s²)².
    """
    y = np.asarray(labels, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    n = y.shape[0]
    mean, centre = y.mean(axis=0), h.mean(axis=0)
    yc, hc = y - mean, h - centre
    slope = np.linalg.solve(hc.T @ hc + ridge * n * np.eye(3), hc.T @ yc).T
    resid = yc - hc @ slope.T
    cov = resid.T @ resid / max(n - 4, 1)
    return mean, slope, centre, floor_cov(cov, min_std)


def condition_on_norm(m: np.ndarray, g: np.ndarray | float, mu: np.ndarray, cov: np.ndarray,
                      obs_var: np.ndarray | float, n_iter: int = GN_ITERATIONS,
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian posterior of a bias b given that the window mean m satisfies ‖m − b‖ = g.

    Prior b ~ N(μ, Σ); observation ‖m − b‖ = g + ε, ε ~ N(0, σ²). Linearised at b_k with
    h = (m − b_k)/‖m − b_k‖ (the measured up), the observation reads hᵀb = y_k with
    y_k = ‖m − b_k‖ − g + hᵀb_k, and Gaussian conditioning gives

        μ_post = μ + Σh·(y_k − hᵀμ)/(hᵀΣh + σ²),   Σ_post = Σ − Σhhᵀ Σ/(hᵀΣh + σ²).

    The first pass linearises at b_0 = μ (the plain formula with y = ‖m − μ‖ − g + hᵀμ,
    which equals ‖m‖ − g ≈ hᵀb for μ = 0); further passes relinearise at the new mean
    (iterated Kalman update = Gauss–Newton for the MAP on the sphere).

    Parameters
    ----------
    m
        (N, 3) window means, m/s².
    g
        (N,) or scalar local gravity, m/s².
    mu
        (3,) or (N, 3) prior means, m/s².
    cov
        (3, 3) or (N, 3, 3) prior covariances, (m/s²)².
    obs_var
        (N,) or scalar σ² of the norm observation, (m/s²)².
    n_iter
        Linearisations (≥ 1).

    Returns
    -------
    mean
        (N, 3) posterior means, m/s².
    cov
        (N, 3, 3) posterior covariances, (m/s²)².
    loglik
        (N,) log density of the observation under the prior, log N(‖m − μ‖ − g; 0, hᵀΣh + σ²)
        at the first linearisation (for mixture weights).
    """
    m = np.asarray(m, dtype=np.float64)
    n = m.shape[0]
    mu_n = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n, 3))
    cov_n = np.broadcast_to(np.asarray(cov, dtype=np.float64), (n, 3, 3))
    g_n = np.broadcast_to(np.asarray(g, dtype=np.float64), (n,))
    var_n = np.broadcast_to(np.asarray(obs_var, dtype=np.float64), (n,))
    b = mu_n.copy()
    loglik = np.zeros(n)
    ch = np.zeros((n, 3))
    s = np.ones(n)
    for k in range(max(1, n_iter)):
        h, r = unit_rows(m - b)
        innovation = r - g_n + np.einsum("ni,ni->n", h, b - mu_n)
        ch = np.einsum("nij,nj->ni", cov_n, h)
        s = np.einsum("ni,ni->n", h, ch) + var_n
        if k == 0:
            loglik = -0.5 * (innovation**2 / s + np.log(2.0 * np.pi * s))
        b = mu_n + ch * (innovation / s)[:, None]
    post = cov_n - np.einsum("ni,nj->nij", ch, ch) / s[:, None, None]
    return b, 0.5 * (post + np.swapaxes(post, 1, 2)), loglik


def mixture_moments(log_weights: np.ndarray, means: np.ndarray, covs: np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and covariance of Gaussian mixtures (law of total variance).

    Parameters
    ----------
    log_weights
        (N, K) unnormalised log weights.
    means
        (N, K, 3) component means.
    covs
        (N, K, 3, 3) component covariances.

    Returns
    -------
    mean
        (N, 3).
    cov
        (N, 3, 3): Σ_k w_k·(C_k + (μ_k − μ̄)(μ_k − μ̄)ᵀ).
    weights
        (N, K) normalised weights.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    w = np.exp(lw - lw.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    mean = np.einsum("nk,nki->ni", w, means)
    d = means - mean[:, None, :]
    cov = np.einsum("nk,nkij->nij", w, covs + np.einsum("nki,nkj->nkij", d, d))
    return mean, cov, w


# ----------------------------------------------------------------------------- gravity-prior


@register
class GravityPrior(Estimator):
    """``gravity-prior``: along-gravity bias from the norm, tangential bias from a learned prior.

    Per window, m is the mean specific force and h = m/‖m‖. The norm of m observes one
    number, ‖m − b‖ = g (to first order hᵀb = ‖m‖ − g), with noise variance σ_y². The prior
    of the window's device is N(μ_d, Σ_d), learned on the training labels; the estimate is
    the Gaussian posterior (:func:`condition_on_norm`): the component along h comes from the
    data, the two tangential ones from the prior, and :meth:`predict_std` = sqrt(diag Σ_post).

    A device not seen in :meth:`fit` (or every device when ``per_device`` is False) gets a
    Gaussian mixture over the training devices' priors with weights ∝ (training windows of
    the device) × N(‖m − μ_d‖ − g; 0, hᵀΣ_d h + σ_y²), each component conditioned on the
    window; the estimate and std are the mixture's mean and covariance (law of total
    variance, :func:`mixture_moments`).

    Learned in :meth:`fit`: μ_d, Σ_d = the labels' mean and covariance per device, every
    eigenvalue floored at (``min_std_mg``)²; σ_y = the RMS over the training windows of the
    exact residual ‖m_j − y_j‖ − g_j at the label y_j (window noise along h plus label
    noise), floored at ``min_obs_std_mg``.

    With ``direction_model`` (an option beyond methods.md, off by default) the prior mean is
    linear in the window's up direction, μ_d(h) = μ_d + C_d·(h − h̄_d), and Σ_d is the
    residual covariance (:func:`direction_prior`): on a rotated campaign the apparent bias
    contains (A − I)·u·g, which a constant prior can only treat as spread.

    Parameters
    ----------
    per_device
        Use the window's device prior when the device was seen in training.
    min_std_mg
        Floor of the prior standard deviation along any direction, mg.
    min_obs_std_mg
        Floor of σ_y, mg.
    direction_model
        Make the prior mean linear in h (see above).
    direction_ridge
        Ridge of that regression, relative to the number of training windows.

    Attributes
    ----------
    means_
        ``{device: (3,) m/s²}``: the training-label mean μ_d.
    slopes_
        ``{device: (3, 3) m/s²}``: C_d (zero without ``direction_model``).
    centres_
        ``{device: (3,)}``: h̄_d (zero without ``direction_model``).
    covs_
        ``{device: (3, 3) (m/s²)²}``.
    counts_
        ``{device: training windows}``.
    obs_std_
        σ_y, m/s².
    """

    name: ClassVar[str] = "gravity-prior"
    order: ClassVar[int] = 50
    needs_fit: ClassVar[bool] = True

    def __init__(self, per_device: bool = True, min_std_mg: float = 0.5, min_obs_std_mg: float = 0.05,
                 direction_model: bool = False, direction_ridge: float = 1e-6) -> None:
        self.per_device = per_device
        self.min_std_mg = min_std_mg
        self.min_obs_std_mg = min_obs_std_mg
        self.direction_model = direction_model
        self.direction_ridge = direction_ridge
        self._check_params()

    def _check_params(self) -> None:
        for key in ("per_device", "direction_model"):
            flag = getattr(self, key)
            if not isinstance(flag, bool):
                raise EstimatorError(f"gravity-prior {key}: expected true or false, found {flag!r}")
        for key in ("min_std_mg", "min_obs_std_mg", "direction_ridge"):
            v = getattr(self, key)
            if not (is_real(v) and math.isfinite(v) and v > 0):
                raise EstimatorError(f"gravity-prior {key}: expected a finite number > 0, found {v!r}")

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> GravityPrior:
        """Learn the device priors and the observation noise."""
        check_inputs(windows, meta, labels)
        self._check_params()
        y = np.asarray(labels, dtype=np.float64)
        if y.shape[0] == 0:
            raise EstimatorError("gravity-prior: expected at least one training window, found none")
        if not np.all(np.isfinite(y)):
            raise EstimatorError("gravity-prior: expected finite labels, found NaN or infinity")
        m = window_means(windows)
        g = g_local_column(meta)
        dev = device_column(meta)
        resid = np.linalg.norm(m - y, axis=1) - g
        self.obs_std_ = max(float(np.sqrt(np.mean(resid**2))), self.min_obs_std_mg * MG)
        h, _ = unit_rows(m)
        self.means_, self.slopes_, self.centres_, self.covs_, self.counts_ = {}, {}, {}, {}, {}
        for d in sorted(set(dev)):
            rows = dev == d
            if self.direction_model:
                prior = direction_prior(y[rows], h[rows], self.min_std_mg * MG, self.direction_ridge)
                self.means_[d], self.slopes_[d], self.centres_[d], self.covs_[d] = prior
            else:
                self.means_[d], self.covs_[d] = gaussian_prior(y[rows], self.min_std_mg * MG)
                self.slopes_[d], self.centres_[d] = np.zeros((3, 3)), np.zeros(3)
            self.counts_[d] = int(np.sum(rows))
        self.domain_ = domain_of(windows, meta)
        return self

    def _prior_mean(self, d: str, h: np.ndarray) -> np.ndarray:
        """Device d's prior mean for windows with up directions h (n, 3): (n, 3) m/s²."""
        return self.means_[d] + (h - self.centres_[d]) @ self.slopes_[d].T

    def _posterior(self, windows: np.ndarray, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Posterior means (N, 3) and covariances (N, 3, 3) of every window."""
        check_inputs(windows, meta)
        check_fitted(self, "means_")
        m = window_means(windows)
        g = g_local_column(meta)
        dev = device_column(meta)
        var = self.obs_std_**2
        h, _ = unit_rows(m)
        mean = np.empty((m.shape[0], 3))
        cov = np.empty((m.shape[0], 3, 3))
        known = np.isin(dev, list(self.means_)) if self.per_device else np.zeros(len(dev), dtype=bool)
        for d in sorted(set(dev[known])):
            rows = dev == d
            mean[rows], cov[rows], _ = condition_on_norm(m[rows], g[rows], self._prior_mean(d, h[rows]),
                                                         self.covs_[d], var)
        rest = ~known
        if rest.any():
            names = sorted(self.means_)
            parts = [condition_on_norm(m[rest], g[rest], self._prior_mean(d, h[rest]), self.covs_[d], var)
                     for d in names]
            logw = np.stack([np.log(self.counts_[d]) + p[2] for d, p in zip(names, parts, strict=True)],
                            axis=1)
            mean[rest], cov[rest], _ = mixture_moments(logw, np.stack([p[0] for p in parts], axis=1),
                                                       np.stack([p[1] for p in parts], axis=1))
        return mean, cov

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior mean bias per window, (N, 3) m/s²."""
        return self._posterior(windows, meta)[0]

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior standard deviation per window and axis, (N, 3) m/s²."""
        cov = self._posterior(windows, meta)[1]
        return np.sqrt(np.clip(np.einsum("nii->ni", cov), 0.0, None))

    # --------------------------------------------------------------------- persistence

    def to_dict(self) -> dict[str, Any]:
        """The fitted estimator as plain JSON-ready data (floats round-trip exactly).

        Returns
        -------
        dict
            ``{"format": "ofbe-gravity-prior/1", "params": {...}, "obs_std": σ_y (m/s²),
            "devices": {device: {"count": int, "mean": [3] m/s², "cov": [[3]×3] (m/s²)²,
            "slope": [[3]×3] m/s², "centre": [3]}}, "training_domain": {...}}`` (the last
            from :class:`~ofbe_model.estimators.domain.TrainingDomain`).
        """
        check_fitted(self, "means_")
        return {
            "format": GRAVITY_PRIOR_FORMAT,
            "params": self.get_params(),
            "obs_std": float(self.obs_std_),
            "devices": {d: {"count": int(self.counts_[d]), "mean": self.means_[d].tolist(),
                            "cov": self.covs_[d].tolist(), "slope": self.slopes_[d].tolist(),
                            "centre": self.centres_[d].tolist()} for d in sorted(self.means_)},
            **({} if getattr(self, "domain_", None) is None else {"training_domain": self.domain_.to_dict()}),
        }

    @classmethod
    def from_dict(cls, data: Any, source: str = "gravity-prior data") -> GravityPrior:
        """A fitted estimator from :meth:`to_dict`'s output.

        Raises
        ------
        EstimatorError
            Naming ``source``, the field, what was expected and what was found.
        """
        def bad(field: str, expected: str, found: Any) -> EstimatorError:
            text = repr(found)
            return EstimatorError(f"{source}: {field}: expected {expected}, found "
                                  f"{text[:80] + '…' if len(text) > 80 else text}")

        if not isinstance(data, dict):
            raise bad("top level", f"a JSON object of format {GRAVITY_PRIOR_FORMAT}", type(data).__name__)
        if data.get("format") != GRAVITY_PRIOR_FORMAT:
            raise bad("format", repr(GRAVITY_PRIOR_FORMAT), data.get("format"))
        params = data.get("params")
        if not isinstance(params, dict):
            raise bad("params", "an object of parameters", params)
        try:
            est = cls(**params)
        except (TypeError, EstimatorError) as exc:
            raise bad("params", "gravity-prior parameters", str(exc)) from None
        obs_std = data.get("obs_std")
        if not (is_real(obs_std) and math.isfinite(obs_std) and obs_std > 0):
            raise bad("obs_std", "a finite number > 0 (m/s²)", obs_std)
        devices = data.get("devices")
        if not isinstance(devices, dict) or not devices:
            raise bad("devices", "a non-empty object of device priors", devices)
        means, covs, counts, slopes, centres = {}, {}, {}, {}, {}
        for d, entry in devices.items():
            if not isinstance(entry, dict):
                raise bad(f"devices.{d}", "an object with count, mean, cov, slope, centre", entry)
            try:
                mean = np.asarray(entry.get("mean"), dtype=np.float64)
                cov = np.asarray(entry.get("cov"), dtype=np.float64)
                slope = np.asarray(entry.get("slope"), dtype=np.float64)
                centre = np.asarray(entry.get("centre"), dtype=np.float64)
            except (TypeError, ValueError):
                raise bad(f"devices.{d}", "numeric mean [3], cov [3][3], slope [3][3], centre [3]",
                          entry) from None
            count = entry.get("count")
            shapes = (("mean", mean, (3,)), ("slope", slope, (3, 3)), ("centre", centre, (3,)))
            for field, arr, shape in shapes:
                if arr.shape != shape or not np.all(np.isfinite(arr)):
                    raise bad(f"devices.{d}.{field}", f"finite numbers of shape {shape}", entry.get(field))
            if cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T) \
                    or np.linalg.eigvalsh(cov).min() <= 0:
                raise bad(f"devices.{d}.cov", "a symmetric positive definite 3×3 matrix ((m/s²)²)",
                          entry.get("cov"))
            if not (is_int(count) and count > 0):
                raise bad(f"devices.{d}.count", "a positive integer", count)
            means[d], covs[d], counts[d], slopes[d], centres[d] = mean, cov, count, slope, centre
        est.obs_std_ = float(obs_std)
        est.means_, est.covs_, est.counts_, est.slopes_, est.centres_ = means, covs, counts, slopes, centres
        est.domain_ = TrainingDomain.from_dict(data.get("training_domain"))
        return est

    def save(self, path: str | Path) -> None:
        """Write :meth:`to_dict` as JSON to ``path``, atomically (no pickle).

        Parameters
        ----------
        path
            Target file (its folder must exist), conventionally ``*.json``.
        """
        text = json.dumps(self.to_dict(), indent=1, sort_keys=True, allow_nan=False) + "\n"
        write_bytes_atomic(path, text.encode("utf-8"))

    @classmethod
    def load(cls, path: str | Path) -> GravityPrior:
        """A fitted estimator saved by :meth:`save`.

        Raises
        ------
        EstimatorError
            The file cannot be read, is not UTF-8 JSON, or is not a gravity-prior of format
            ``ofbe-gravity-prior/1`` (the message names the file, what was expected and what
            was found). Nothing in the file is ever executed.
        """
        path = Path(path)
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise EstimatorError(f"{path}: expected a saved gravity-prior ({GRAVITY_PRIOR_FORMAT} JSON), "
                                 f"found an unreadable file ({exc.strerror or exc})") from None
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EstimatorError(f"{path}: expected a saved gravity-prior ({GRAVITY_PRIOR_FORMAT} JSON), "
                                 f"found a file that is not JSON ({exc})") from None
        return cls.from_dict(data, source=str(path))
