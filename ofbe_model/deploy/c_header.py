"""The ``gravity-prior`` estimator as a self-contained C99 header (products.md §Exports, ``c-header``).

:func:`export_c_header` writes one header with ``static const float`` tables (per device:
the prior mean μ_d, covariance Σ_d, direction-model slope C_d and centre h̄_d, training
window count; σ_y; a device-id table) and a reference function

.. code-block:: c

    int ofbe_gravity_prior_predict(const float *window /* T×3 m/s², row-major */, int T,
                                   float g_local /* m/s² */, int device_index /* -1: unknown */,
                                   float bias_out[3] /* m/s² */, float std_out[3] /* m/s² */);

that does what :meth:`GravityPrior.predict` and :meth:`GravityPrior.predict_std` do, in
float32 with only ``<math.h>`` and no dynamic allocation: the window mean m (compensated
summation of the deviations from the first sample, kept as a float32 pair m + m_lo), its
unit direction h, the device's prior
mean μ_d + C_d·(h − h̄_d), the Gauss–Newton conditioning on ‖m − b‖ = g
(:func:`~ofbe_model.estimators.priors.condition_on_norm`, ``GN_ITERATIONS`` passes), and for
an unknown device (``device_index`` −1, or every device when the prior was fitted with
``per_device=False``) the mixture over the devices with weights ∝ count_d ×
N(‖m − μ_d‖ − g; 0, hᵀΣ_d h + σ_y²) (:func:`~ofbe_model.estimators.priors.mixture_moments`),
computed in three passes over the devices so the stack stays constant whatever their number.
The norm residual ‖m − b‖ − g, a difference of two ~9.8 m/s² numbers, is computed from
‖m + m_lo‖² − g² with exact products (``fmaf``) and a compensated sum, so it keeps float32's
relative precision: one device's posterior agrees with Python to ~1e-6 m/s², the mixture to
~2e-5 m/s² on biases of ~1 m/s² (its log weights, of order 10²–10³, keep a float32 ulp).

Device ``i`` of the tables is the i-th device id in sorted order (:func:`device_indices`).

The reference harness (:func:`compile_harness`, :func:`run_harness`) compiles a small C
program around a header with the system C compiler and runs it on windows from a binary file:
the tests compare it with the Python estimator, the benchmark times it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_model.estimators.base import EstimatorError
from ofbe_model.estimators.common import GN_ITERATIONS
from ofbe_model.estimators.priors import GravityPrior

#: Return codes of the C function (also #defined in the header).
C_OK, C_EINVAL, C_EDEVICE, C_EWINDOW = 0, -1, -2, -3
_NAME_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.")
#: Bytes of a pointer on the ESP32 (Xtensa LX6/LX7 and RISC-V cores are 32-bit).
POINTER_BYTES = 4


# ---------------------------------------------------------------------------------------------
# Formatting


def _f(value: float) -> str:
    """A C float literal that converts to exactly float32(value)."""
    text = f"{float(np.float32(value)):.9e}"
    return ("-" if text.startswith("-") else " ") + text.lstrip("-") + "f"


def _c_string(text: str) -> str:
    """A C string literal of text's UTF-8 bytes (printable ASCII kept, the rest octal-escaped)."""
    out = []
    for b in text.encode("utf-8"):
        ch = chr(b)
        out.append(ch if 0x20 <= b < 0x7F and ch not in '"\\?' else f"\\{b:03o}")
    return '"' + "".join(out) + '"'


def _comment_safe(text: str) -> str:
    return text.encode("ascii", "backslashreplace").decode("ascii").replace("*/", "* /")


def _rows(values: np.ndarray, indent: str) -> str:
    """Nested C initialiser of a float array, one device per line."""
    def nested(a: np.ndarray) -> str:
        if a.ndim == 0:
            return _f(float(a))
        return "{" + ", ".join(nested(x) for x in a) + "}"

    return ",\n".join(f"{indent}{nested(row)} /* {i} */" for i, row in enumerate(values))


def _load(prior: GravityPrior | str | Path) -> tuple[GravityPrior, str]:
    if isinstance(prior, GravityPrior):
        if not hasattr(prior, "means_"):
            raise EstimatorError("prior: expected a fitted gravity-prior, found it unfitted (call fit first)")
        return prior, "a fitted GravityPrior"
    if isinstance(prior, str | Path):
        return GravityPrior.load(prior), str(prior)
    raise EstimatorError(f"prior: expected a GravityPrior or the path of its JSON, found "
                         f"{type(prior).__name__}")


def device_indices(prior: GravityPrior, devices: Sequence[str]) -> np.ndarray:
    """The ``device_index`` to pass to the C function for each device id.

    Returns
    -------
    np.ndarray
        (N,) int32: the device's row in the header's tables (sorted ids), −1 for a device
        the prior was not fitted on.
    """
    order = {d: i for i, d in enumerate(sorted(prior.means_))}
    return np.array([order.get(str(d), -1) for d in devices], dtype=np.int32)


def table_bytes(prior: GravityPrior, pointer_bytes: int = POINTER_BYTES) -> int:
    """Bytes of the header's constant tables on the target: floats, id strings and their pointers."""
    n = len(prior.means_)
    floats = 1 + n * (1 + 3 + 9 + 9 + 3)
    strings = sum(len(d.encode("utf-8")) + 1 for d in prior.means_)
    return 4 * floats + strings + pointer_bytes * n


# ---------------------------------------------------------------------------------------------
# The header

_FUNCTIONS = r"""
/* Prior mean of device d for a window of up direction h: mu_d + C_d (h - hbar_d), m/s^2. */
static void ofbe_gp_prior_mean(int d, const float h[3], float mu[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        mu[i] = ofbe_gp_mean[d][i] + ofbe_gp_slope[d][i][0] * (h[0] - ofbe_gp_centre[d][0])
              + ofbe_gp_slope[d][i][1] * (h[1] - ofbe_gp_centre[d][1])
              + ofbe_gp_slope[d][i][2] * (h[2] - ofbe_gp_centre[d][2]);
    }
}

/* |m + m_lo|^2 - g^2 without the float32 cancellation: exact products (fmaf), compensated
 * (Neumaier) sum; the window's norm residual needs about 1e-7 m/s^2 out of 9.8. */
static float ofbe_gp_norm2_minus_g2(const float m[3], const float m_lo[3], float g)
{
    float p[4], err = 0.0f, s, t;
    int i;
    for (i = 0; i < 3; ++i) {
        p[i] = m[i] * m[i];
        err += fmaf(m[i], m[i], -p[i]) + 2.0f * m[i] * m_lo[i];
    }
    p[3] = -(g * g);
    err -= fmaf(g, g, p[3]);
    s = p[0];
    for (i = 1; i < 4; ++i) {
        t = s + p[i];
        err += fabsf(s) >= fabsf(p[i]) ? (s - t) + p[i] : (p[i] - t) + s;
        s = t;
    }
    return s + err;
}

/* Gaussian posterior of the bias b given |m - b| = g (prior N(mu, cov), noise variance var):
 * iterated linearisation at b_k with h = (m - b_k)/|m - b_k|, innovation
 * |m - b_k| - g + h.(b_k - mu), s = h'cov h + var, b_{k+1} = mu + cov h innovation / s;
 * post = cov - (cov h)(cov h)'/s; loglik = log N(innovation; 0, s) at the first pass.
 * The window mean is m + m_lo; c0 = |m + m_lo|^2 - g^2, so that |m - b| - g is computed as
 * (c0 - 2 (m + m_lo).b + b.b) / (|m - b| + g) without cancellation. */
static void ofbe_gp_condition(const float m[3], const float m_lo[3], float c0, float g, const float mu[3],
                              const float cov[3][3], float var, float b[3], float post[3][3], float *loglik)
{
    float ch[3] = {0.0f, 0.0f, 0.0f};
    float s = 1.0f;
    int i, j, k;
    for (i = 0; i < 3; ++i) b[i] = mu[i];
    *loglik = 0.0f;
    for (k = 0; k < OFBE_GP_GN_ITERATIONS; ++k) {
        float h[3], q, r, innovation, gain;
        q = c0 - 2.0f * ((m[0] + m_lo[0]) * b[0] + (m[1] + m_lo[1]) * b[1] + (m[2] + m_lo[2]) * b[2])
            + (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        r = sqrtf(fmaxf(g * g + q, 0.0f));
        for (i = 0; i < 3; ++i) h[i] = (m[i] - b[i]) / r;
        innovation = q / (r + g) + (h[0] * (b[0] - mu[0]) + h[1] * (b[1] - mu[1]) + h[2] * (b[2] - mu[2]));
        for (i = 0; i < 3; ++i) ch[i] = cov[i][0] * h[0] + cov[i][1] * h[1] + cov[i][2] * h[2];
        s = h[0] * ch[0] + h[1] * ch[1] + h[2] * ch[2] + var;
        if (k == 0) *loglik = -0.5f * (innovation * innovation / s + logf(6.28318531f * s));
        gain = innovation / s;
        for (i = 0; i < 3; ++i) b[i] = mu[i] + ch[i] * gain;
    }
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) post[i][j] = cov[i][j] - ch[i] * ch[j] / s;
}

/* Device d's component for the window: posterior mean b, covariance post, log mixture weight. */
static float ofbe_gp_component(int d, const float m[3], const float m_lo[3], float c0, const float h[3],
                               float g, float var, float b[3], float post[3][3])
{
    float mu[3], loglik;
    ofbe_gp_prior_mean(d, h, mu);
    ofbe_gp_condition(m, m_lo, c0, g, mu, ofbe_gp_cov[d], var, b, post, &loglik);
    return logf(ofbe_gp_count[d]) + loglik;
}

/* The bias of one stationary window and its standard deviation (GravityPrior.predict and
 * predict_std).
 *   window        T x 3 specific force, m/s^2, row-major: x0 y0 z0 x1 y1 z1 ... (sensor frame)
 *   T             samples in the window (>= 1)
 *   g_local       local gravity magnitude, m/s^2 (> 0)
 *   device_index  row of the device in the tables (ofbe_gp_device_ids), or -1 for a device the
 *                 prior was not fitted on: the mixture over all devices (always the mixture
 *                 when OFBE_GP_PER_DEVICE is 0)
 *   bias_out      posterior mean bias, m/s^2
 *   std_out       posterior standard deviation per axis, m/s^2
 * Returns OFBE_GP_OK, or OFBE_GP_EINVAL (null pointer, T < 1, g_local not finite and > 0),
 * OFBE_GP_EDEVICE (device_index not in -1 .. OFBE_GP_N_DEVICES - 1), OFBE_GP_EWINDOW (window
 * mean not finite or zero); the outputs are untouched on error. */
static OFBE_GP_UNUSED int ofbe_gravity_prior_predict(const float *window, int T, float g_local,
                                                     int device_index, float bias_out[3], float std_out[3])
{
    float x0[3], sum[3] = {0.0f, 0.0f, 0.0f}, comp[3] = {0.0f, 0.0f, 0.0f};
    float m[3], m_lo[3], h[3], norm, c0, var, bias[3], cov[3][3];
    long t;
    int a, i, j, d;
    if (window == 0 || bias_out == 0 || std_out == 0 || T < 1 || !isfinite(g_local) || !(g_local > 0.0f))
        return OFBE_GP_EINVAL;
    if (device_index < -1 || device_index >= OFBE_GP_N_DEVICES) return OFBE_GP_EDEVICE;
    /* window mean: Kahan sums of the deviations from the first sample */
    for (a = 0; a < 3; ++a) x0[a] = window[a];
    for (t = 1; t < (long)T; ++t) {
        for (a = 0; a < 3; ++a) {
            float y = (window[3L * t + a] - x0[a]) - comp[a];
            float s = sum[a] + y;
            comp[a] = (s - sum[a]) - y;
            sum[a] = s;
        }
    }
    for (a = 0; a < 3; ++a) {
        /* m + m_lo = x0 + (sum - comp) / T, m rounded to float32 (TwoSum for the low part) */
        float dev = sum[a] / (float)T, back;
        m[a] = x0[a] + dev;
        back = m[a] - x0[a];
        m_lo[a] = ((x0[a] - (m[a] - back)) + (dev - back)) - comp[a] / (float)T;
    }
    norm = sqrtf(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    if (!isfinite(norm) || !(norm > 0.0f)) return OFBE_GP_EWINDOW;
    for (a = 0; a < 3; ++a) h[a] = m[a] / norm;
    var = ofbe_gp_obs_std * ofbe_gp_obs_std;
    c0 = ofbe_gp_norm2_minus_g2(m, m_lo, g_local);
    if (OFBE_GP_PER_DEVICE && device_index >= 0) {
        (void)ofbe_gp_component(device_index, m, m_lo, c0, h, g_local, var, bias, cov);
    } else {
        /* mixture (law of total variance): pass 1 the largest log weight, pass 2 the mean,
         * pass 3 the covariance; each pass recomputes the components (no per-device storage) */
        float b[3], post[3][3], lw, lw_max = 0.0f, total = 0.0f, w;
        for (d = 0; d < OFBE_GP_N_DEVICES; ++d) {
            lw = ofbe_gp_component(d, m, m_lo, c0, h, g_local, var, b, post);
            if (d == 0 || lw > lw_max) lw_max = lw;
        }
        for (i = 0; i < 3; ++i) bias[i] = 0.0f;
        for (d = 0; d < OFBE_GP_N_DEVICES; ++d) {
            w = expf(ofbe_gp_component(d, m, m_lo, c0, h, g_local, var, b, post) - lw_max);
            total += w;
            for (i = 0; i < 3; ++i) bias[i] += w * b[i];
        }
        for (i = 0; i < 3; ++i) bias[i] /= total;
        for (i = 0; i < 3; ++i)
            for (j = 0; j < 3; ++j) cov[i][j] = 0.0f;
        for (d = 0; d < OFBE_GP_N_DEVICES; ++d) {
            w = expf(ofbe_gp_component(d, m, m_lo, c0, h, g_local, var, b, post) - lw_max) / total;
            for (i = 0; i < 3; ++i)
                for (j = 0; j < 3; ++j) cov[i][j] += w * (post[i][j] + (b[i] - bias[i]) * (b[j] - bias[j]));
        }
    }
    for (i = 0; i < 3; ++i) {
        bias_out[i] = bias[i];
        std_out[i] = sqrtf(cov[i][i] > 0.0f ? cov[i][i] : 0.0f);
    }
    return OFBE_GP_OK;
}
"""


def header_text(prior: GravityPrior, *, name: str = "gravity_prior", source: str = "a fitted GravityPrior",
                ) -> str:
    """The C99 header of a fitted prior (what :func:`export_c_header` writes).

    Parameters
    ----------
    prior
        A fitted :class:`GravityPrior`.
    name
        Used in the include guard and ``OFBE_GP_NAME``.
    source
        Where the prior came from, for the header's comment.

    Returns
    -------
    str
        ASCII C source.
    """
    devices = sorted(prior.means_)
    n = len(devices)
    guard = "OFBE_GP_" + "".join(c if c.isalnum() else "_" for c in name.upper()) + "_H"
    params = ", ".join(f"{k}={v!r}" for k, v in prior.get_params().items())
    domain = getattr(prior, "domain_", None)
    trained = (f" * Trained on {domain.n_windows} windows of {domain.window_length} samples, g_local "
               f"{domain.g_local[0]:.6g}..{domain.g_local[1]:.6g} m/s^2"
               + (f", {domain.fs_hz[0]:.6g}..{domain.fs_hz[1]:.6g} Hz" if domain.fs_hz else "") + ".\n"
               if domain is not None else "")
    ids = ",\n".join(f"    {_c_string(d)} /* {i} */" for i, d in enumerate(devices))
    head = f"""/*
 * {name}.h -- the ofbe "gravity-prior" accelerometer-bias estimator as a self-contained C99 header.
 *
 * Generated by ofbe {_comment_safe(__version__)} (ofbe_model.deploy.c_header) from {_comment_safe(source)};
 * do not edit: export again. Estimator parameters: {_comment_safe(params)}.
{trained} *
 * Units: specific force, biases and standard deviations in m/s^2; covariances in (m/s^2)^2; the
 * up direction h and the direction-model centre are unit vectors (dimensionless); the slope is
 * m/s^2 per unit of h. Axes x, y, z of the sensor frame.
 *
 * ofbe_gravity_prior_predict() computes exactly GravityPrior.predict / predict_std, in float32:
 * m = mean of the window, h = m/|m|, prior N(mu_d + C_d (h - hbar_d), Sigma_d) of the device,
 * conditioned on |m - b| = g_local with noise sigma_y (OFBE_GP_GN_ITERATIONS Gauss-Newton passes);
 * for an unknown device a Gaussian mixture over the devices, weights count_d * N(innovation; 0, s_d).
 * Needs only <math.h> (link with -lm); no dynamic allocation, a few hundred bytes of stack.
 * Everything is static: include it in any number of translation units (one prior per unit).
 * Do not compile with -ffast-math: it removes the compensated summation of the window mean.
 */
#ifndef {guard}
#define {guard}

#include <math.h>

#if defined(__GNUC__) || defined(__clang__)
#define OFBE_GP_UNUSED __attribute__((unused))
#else
#define OFBE_GP_UNUSED
#endif

#define OFBE_GP_VERSION {_c_string(__version__)} /* ofbe version that wrote this header */
#define OFBE_GP_NAME {_c_string(name)}
#define OFBE_GP_N_DEVICES {n} /* devices in the tables */
#define OFBE_GP_PER_DEVICE {int(bool(prior.per_device))} /* 0: every window uses the mixture */
#define OFBE_GP_GN_ITERATIONS {int(GN_ITERATIONS)} /* linearisations of the norm observation */
#define OFBE_GP_OK {C_OK}
#define OFBE_GP_EINVAL ({C_EINVAL})
#define OFBE_GP_EDEVICE ({C_EDEVICE})
#define OFBE_GP_EWINDOW ({C_EWINDOW})

/* sigma_y: standard deviation of the norm observation |m - b| - g, m/s^2 */
static const float ofbe_gp_obs_std OFBE_GP_UNUSED = {_f(prior.obs_std_).strip()};

/* device ids (UTF-8); device_index i is row i of every table below */
static const char *const ofbe_gp_device_ids[OFBE_GP_N_DEVICES] OFBE_GP_UNUSED = {{
{ids}
}};

/* training windows per device: the prior weight of the device in the mixture */
static const float ofbe_gp_count[OFBE_GP_N_DEVICES] OFBE_GP_UNUSED = {{
{_rows(np.array([float(prior.counts_[d]) for d in devices]), "    ")}
}};

/* mu_d: prior mean bias (mean training label), m/s^2 */
static const float ofbe_gp_mean[OFBE_GP_N_DEVICES][3] OFBE_GP_UNUSED = {{
{_rows(np.array([prior.means_[d] for d in devices]), "    ")}
}};

/* Sigma_d: prior covariance (residual covariance with the direction model), (m/s^2)^2 */
static const float ofbe_gp_cov[OFBE_GP_N_DEVICES][3][3] OFBE_GP_UNUSED = {{
{_rows(np.array([prior.covs_[d] for d in devices]), "    ")}
}};

/* C_d: direction-model slope, m/s^2 per unit of h (zero without the direction model) */
static const float ofbe_gp_slope[OFBE_GP_N_DEVICES][3][3] OFBE_GP_UNUSED = {{
{_rows(np.array([prior.slopes_[d] for d in devices]), "    ")}
}};

/* hbar_d: direction-model centre, mean up direction of the training windows (zero without it) */
static const float ofbe_gp_centre[OFBE_GP_N_DEVICES][3] OFBE_GP_UNUSED = {{
{_rows(np.array([prior.centres_[d] for d in devices]), "    ")}
}};
"""
    return head + _FUNCTIONS + f"\n#endif /* {guard} */\n"


def export_c_header(prior: GravityPrior | str | Path, out_path: str | Path, *,
                    name: str = "gravity_prior") -> Path:
    """Write a fitted gravity-prior as a self-contained C99 header.

    Parameters
    ----------
    prior
        A fitted :class:`GravityPrior`, or the path of its JSON (:meth:`GravityPrior.save`).
    out_path
        The header file (its folder is created); an existing folder gets ``<name>.h``.
    name
        Letters, digits, ``_ - .`` starting with a letter: the include guard and
        ``OFBE_GP_NAME``.

    Returns
    -------
    Path
        The written header.

    Raises
    ------
    EstimatorError
        An unfitted prior, a file that is not a saved gravity-prior (naming it), or a bad name.
    """
    if not (isinstance(name, str) and name and name[0].isalpha() and set(name) <= _NAME_CHARS):
        raise EstimatorError(f"name: expected letters, digits, '_', '-' and '.', starting with a letter, "
                             f"found {name!r}")
    est, source = _load(prior)
    path = Path(out_path)
    if path.is_dir():
        path = path / f"{name}.h"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, header_text(est, name=name, source=source).encode("ascii"))
    return path


# ---------------------------------------------------------------------------------------------
# Reference harness: compile and run the C function on windows from a file

HARNESS_C = r"""/* ofbe gravity-prior harness: IN OUT [REPEATS].
 * IN: int32 N, int32 T, then N records of int32 device_index, float32 g_local, float32 window[T][3].
 * OUT: N records of int32 status, float32 bias[3], float32 std[3] (native byte order).
 * With REPEATS > 0 every window is estimated REPEATS more times and the CPU seconds per call
 * are printed on stdout. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include HEADER

int main(int argc, char **argv)
{
    FILE *in, *out;
    int32_t head[2], n, T, i, r, repeats = argc > 3 ? atoi(argv[3]) : 0;
    int32_t *dev;
    float *g, *x, bias[3], std[3];
    volatile float sink = 0.0f;
    if (argc < 3) { fprintf(stderr, "usage: %s IN OUT [REPEATS]\n", argv[0]); return 2; }
    in = fopen(argv[1], "rb");
    if (in == NULL || fread(head, sizeof head[0], 2, in) != 2) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 1;
    }
    n = head[0];
    T = head[1];
    dev = malloc(sizeof *dev * (size_t)n);
    g = malloc(sizeof *g * (size_t)n);
    x = malloc(sizeof *x * 3u * (size_t)T * (size_t)n);
    if (dev == NULL || g == NULL || x == NULL) { fprintf(stderr, "out of memory\n"); return 1; }
    for (i = 0; i < n; ++i) {
        if (fread(dev + i, sizeof *dev, 1, in) != 1 || fread(g + i, sizeof *g, 1, in) != 1
            || fread(x + 3 * (size_t)T * (size_t)i, sizeof *x, 3 * (size_t)T, in) != 3 * (size_t)T) {
            fprintf(stderr, "%s: short file\n", argv[1]);
            return 1;
        }
    }
    fclose(in);
    out = fopen(argv[2], "wb");
    if (out == NULL) { fprintf(stderr, "cannot write %s\n", argv[2]); return 1; }
    for (i = 0; i < n; ++i) {
        int32_t status = ofbe_gravity_prior_predict(x + 3 * (size_t)T * (size_t)i, T, g[i], dev[i],
                                                    bias, std);
        fwrite(&status, sizeof status, 1, out);
        fwrite(bias, sizeof bias[0], 3, out);
        fwrite(std, sizeof std[0], 3, out);
    }
    fclose(out);
    if (repeats > 0) {
        clock_t t0 = clock();
        for (r = 0; r < repeats; ++r)
            for (i = 0; i < n; ++i) {
                ofbe_gravity_prior_predict(x + 3 * (size_t)T * (size_t)i, T, g[i], dev[i], bias, std);
                sink += bias[0] + std[2];
            }
        printf("%.9e\n", (double)(clock() - t0) / CLOCKS_PER_SEC / ((double)repeats * n));
    }
    free(dev);
    free(g);
    free(x);
    (void)sink;
    return 0;
}
"""


def find_c_compiler() -> str | None:
    """The system C compiler: ``$CC`` if it names a program, else ``cc``, ``gcc`` or ``clang``."""
    for candidate in (os.environ.get("CC", ""), "cc", "gcc", "clang"):
        found = shutil.which(candidate) if candidate else None
        if found:
            return found
    return None


def compile_harness(header: str | Path, work_dir: str | Path, *, compiler: str | None = None,
                    flags: Sequence[str] = ("-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic")) -> Path:
    """Compile :data:`HARNESS_C` around a header.

    Parameters
    ----------
    header
        A header written by :func:`export_c_header`.
    work_dir
        Folder for the source and the program.
    compiler
        C compiler (default :func:`find_c_compiler`).
    flags
        Compiler flags (``-lm`` is always added).

    Returns
    -------
    Path
        The program.

    Raises
    ------
    EstimatorError
        No compiler, or the compilation failed (its first error lines in the message).
    """
    cc = compiler or find_c_compiler()
    if cc is None:
        raise EstimatorError("cc: expected a C compiler (cc, gcc or clang on PATH, or $CC), found none")
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    source = work / "ofbe_gp_harness.c"
    source.write_text(HARNESS_C.replace("HEADER", f'"{Path(header).resolve()}"'), encoding="ascii")
    exe = work / "ofbe_gp_harness"
    done = subprocess.run([cc, *flags, "-o", str(exe), str(source), "-lm"], capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        raise EstimatorError(f"{header}: expected a header that compiles with {cc} {' '.join(flags)}, found "
                             f"errors: {' | '.join(done.stderr.strip().splitlines()[:5])}")
    return exe


def run_harness(exe: str | Path, windows: np.ndarray, g_local: np.ndarray, device_index: np.ndarray,
                work_dir: str | Path, *, repeats: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                     float | None]:
    """Run the compiled harness on windows.

    Parameters
    ----------
    exe
        From :func:`compile_harness`.
    windows
        (N, T, 3) m/s² (written as float32).
    g_local
        (N,) m/s².
    device_index
        (N,) rows of the header's tables, −1 for unknown devices (:func:`device_indices`).
    work_dir
        Folder for the input and output files.
    repeats
        Extra timed passes over all windows (0: none).

    Returns
    -------
    bias, std
        (N, 3) float32, m/s².
    status
        (N,) int32 return codes.
    seconds
        CPU seconds per call (None without ``repeats``).

    Raises
    ------
    EstimatorError
        The program failed.
    """
    x = np.ascontiguousarray(windows, dtype="=f4")
    n, length = x.shape[0], x.shape[1]
    record = np.dtype([("device", "=i4"), ("g", "=f4"), ("x", "=f4", (length, 3))])
    rows = np.empty(n, dtype=record)
    rows["device"], rows["g"], rows["x"] = device_index, g_local, x
    work = Path(work_dir)
    src, dst = work / "ofbe_gp_windows.bin", work / "ofbe_gp_estimates.bin"
    src.write_bytes(np.array([n, length], dtype="=i4").tobytes() + rows.tobytes())
    done = subprocess.run([str(exe), str(src), str(dst), str(int(repeats))], capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        raise EstimatorError(f"{exe}: expected exit status 0, found {done.returncode}: {done.stderr.strip()}")
    result = np.frombuffer(dst.read_bytes(), dtype=np.dtype([("status", "=i4"), ("bias", "=f4", 3),
                                                               ("std", "=f4", 3)]))
    seconds = float(done.stdout.split()[0]) if repeats > 0 else None
    return result["bias"].copy(), result["std"].copy(), result["status"].copy(), seconds
