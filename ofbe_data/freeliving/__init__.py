"""Free-living calibration of wearables: calibration from a recording's own still periods.

- :mod:`~ofbe_data.freeliving.epochs`: epoch tables (one row per epoch: means and standard
  deviations per axis, g, and the temperature, °C: GGIR's ``spheredata`` layout) and their csv
  reader;
- :mod:`~ofbe_data.freeliving.ggir`: GGIR's ``g.calibrate`` (wadpac/GGIR, R/g.calibrate.R),
  reproduced on epochs: still-epoch selection, the sphere-coverage rule, the iteratively
  re-weighted fit with centred temperature, the calibration errors and GGIR's QC outcomes.

The command is ``ofbe-autocal`` (:mod:`ofbe_data.cli.autocal`); docs/free-living.md describes
it. This package may import :mod:`ofbe_data.core`, :mod:`ofbe_data.io` (raw readers, for the
slices to come) and :mod:`ofbe_data.labelling` (the calibration ladder, for ``--mode ofbe``);
never the simulator, the dataset or reports wings, or :mod:`ofbe_model`.
"""

from ofbe_data.freeliving.epochs import EpochFileError, EpochTable, parse_epoch_csv, read_epoch_csv
from ofbe_data.freeliving.ggir import (
    QC_DONE,
    QC_DONE_NO_TEMPERATURE,
    QC_MESSAGES,
    QC_NO_STILL,
    QC_NOT_DECREASED,
    QC_NOT_GOOD_ENOUGH,
    QC_SPHERE_NOT_POPULATED,
    QC_TOO_SHORT,
    GgirResult,
    GgirSettings,
    apply_ggir,
    fit_sphere,
    ggir_calibrate,
)

__all__ = [
    "QC_DONE",
    "QC_DONE_NO_TEMPERATURE",
    "QC_MESSAGES",
    "QC_NOT_DECREASED",
    "QC_NOT_GOOD_ENOUGH",
    "QC_NO_STILL",
    "QC_SPHERE_NOT_POPULATED",
    "QC_TOO_SHORT",
    "EpochFileError",
    "EpochTable",
    "GgirResult",
    "GgirSettings",
    "apply_ggir",
    "fit_sphere",
    "ggir_calibrate",
    "parse_epoch_csv",
    "read_epoch_csv",
]
