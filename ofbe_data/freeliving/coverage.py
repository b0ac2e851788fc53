"""Whether a recording's still epochs populate the sphere enough to calibrate, and where not.

The bench asks for poses on both faces of every axis (:mod:`ofbe_data.labelling.multiposition._six_faces`,
:mod:`ofbe_data.labelling.multiposition._next_pose`); a wearable is not placed, it is worn, so its still
epochs fall where the wearer left it. The rule generalises the six faces to wear:

    every signed axis (+x, −x, +y, −y, +z, −z) must have pointed within
    :data:`COVERAGE_DEG` (45°) of straight up in at least :data:`MIN_EPOCHS_PER_FACE` still
    epoch(s): its raw mean has a component above cos 45° ≈ 0.71 of its length along it.

An axis seen only from one side leaves its offset and scale entangled (the bench's
``scale_leak_mg``: an unseen scale error moves the offset); seen from both sides within 45°,
each axis' offset is fixed by the difference of its two sides as on the bench. GGIR's rule
(some mean below −0.3 g and some above +0.3 g on every axis) is the same rule with 72.5°. The
directions missing are named in the QC line, which is the next-pose advice of the bench
turned into advice for wear: lay the device, or wear it, so that those axes point up.

Whether the richer models (scales, non-orthogonality, temperature) are determined is left to
the ladder's condition rules (:mod:`ofbe_data.freeliving.ladder`); this rule only decides
whether a calibration is attempted at all.
"""

from __future__ import annotations

import numpy as np

from ofbe_data.labelling.multiposition import FACE_ORDER

COVERAGE_DEG = 45.0
"""A still epoch counts for a signed axis when its mean lies within this angle of it."""
MIN_EPOCHS_PER_FACE = 1
"""Still epochs needed within :data:`COVERAGE_DEG` of every signed axis."""


def face_directions() -> np.ndarray:
    """Shape (6, 3): the unit vectors of the signed axes in :data:`FACE_ORDER` (+x, −x, +y, −y, +z, −z)."""
    out = np.zeros((6, 3))
    for k, name in enumerate(FACE_ORDER):
        out[k, "xyz".index(name[1])] = 1.0 if name[0] == "+" else -1.0
    return out


def face_counts(means_g: np.ndarray, coverage_deg: float = COVERAGE_DEG) -> np.ndarray:
    """Still epochs within ``coverage_deg`` of each signed axis.

    Parameters
    ----------
    means_g
        Shape (n, 3): the still epochs' raw means, g (a zero mean points nowhere and counts for none).
    coverage_deg
        The cone's half angle, degrees.

    Returns
    -------
    np.ndarray
        Shape (6,), int, in :data:`FACE_ORDER`.
    """
    m = np.asarray(means_g, dtype=np.float64).reshape(-1, 3)
    norms = np.sqrt(np.sum(m * m, axis=1))
    cosine = (m @ face_directions().T) / np.where(norms > 0, norms, np.inf)[:, None]
    return np.sum(cosine >= np.cos(np.radians(coverage_deg)), axis=0).astype(np.int64)


def nearest_angles_deg(means_g: np.ndarray) -> np.ndarray:
    """Shape (6,): the angle from each signed axis (:data:`FACE_ORDER`) to the nearest still epoch's
    mean, degrees (180 without epochs)."""
    m = np.asarray(means_g, dtype=np.float64).reshape(-1, 3)
    norms = np.sqrt(np.sum(m * m, axis=1))
    m = m[norms > 0] / norms[norms > 0, None]
    if m.shape[0] == 0:
        return np.full(6, 180.0)
    cosine = np.clip(np.max(m @ face_directions().T, axis=0), -1.0, 1.0)
    return np.degrees(np.arccos(cosine))


def missing_faces(means_g: np.ndarray, coverage_deg: float = COVERAGE_DEG,
                  min_epochs: int = MIN_EPOCHS_PER_FACE) -> tuple[str, ...]:
    """The signed axes (``+x`` … ``-z``, :data:`FACE_ORDER`) with fewer than ``min_epochs`` still
    epochs within ``coverage_deg``; empty when the sphere is populated."""
    counts = face_counts(means_g, coverage_deg)
    return tuple(name for name, count in zip(FACE_ORDER, counts, strict=True) if count < min_epochs)


def coverage_words(missing: tuple[str, ...], coverage_deg: float = COVERAGE_DEG) -> str:
    """``no still epoch within 45° of -x, +z`` for the signed axes ``missing``."""
    return f"no still epoch within {coverage_deg:g}° of {', '.join(missing)}"
