"""Free-living calibration of wearables: calibration from a recording's own still periods.

- :mod:`~ofbe_data.freeliving.epochs`: epoch tables (one row per epoch: means and standard
  deviations per axis, g, and the temperature, °C: GGIR's ``spheredata`` layout) and their csv
  reader;
- :mod:`~ofbe_data.freeliving.ggir`: GGIR's ``g.calibrate`` (wadpac/GGIR, R/g.calibrate.R),
  reproduced on epochs: still-epoch selection, the sphere-coverage rule, the iteratively
  re-weighted fit with centred temperature, the calibration errors and GGIR's QC outcomes.
- :mod:`~ofbe_data.freeliving.robust`: one model of ofbe's calibration ladder fitted to still
  epochs with robust (Huber, then bisquare) weights and jackknife standard errors over postures;
- :mod:`~ofbe_data.freeliving.ladder`: the ladder's choice for wear (determination, Wald tests);
- :mod:`~ofbe_data.freeliving.coverage`: the coverage rule and the directions that lack still epochs;
- :mod:`~ofbe_data.freeliving.ofbe`: ``--mode ofbe`` for one recording (idle epochs, still epochs,
  coverage, ladder, QC) and its coefficients in ofbe's and GGIR's conventions;
- :mod:`~ofbe_data.freeliving.summary`: ``summary.csv``, ``summary.parquet`` and the epochs files;
- :mod:`~ofbe_data.freeliving.raw`: raw wearable files (``.cwa``, ``.bin``, ``.gt3x``, csv of
  samples) made into GGIR's epochs (:func:`read_raw_epochs`); the readers are
  :mod:`~ofbe_data.freeliving.wearables` (one interface), ofbe's own block readers
  :mod:`~ofbe_data.freeliving.axivity`, :mod:`~ofbe_data.freeliving.geneactiv` and
  :mod:`~ofbe_data.freeliving.actigraph`, :mod:`~ofbe_data.freeliving.blocks` (GGIR's resampling
  and bad blocks) and :mod:`~ofbe_data.freeliving.hashing` (each file's sha256 from the pass that
  reads it);
- :mod:`~ofbe_data.freeliving.params`: ``ofbe-autocal``'s settings and its ``--params`` file;
- :mod:`~ofbe_data.freeliving.plots`: ``--plots``' figure per file (still epochs on the sphere and
  the norm error against temperature, before and after).

The command is ``ofbe-autocal`` (:mod:`ofbe_data.cli.autocal`); docs/free-living.md describes
it. This package may import :mod:`ofbe_data.core`, :mod:`ofbe_data.io` (raw readers, for the
slices to come) and :mod:`ofbe_data.labelling` (the calibration ladder, for ``--mode ofbe``);
never the simulator, the dataset or reports wings, or :mod:`ofbe_model`.
"""

from ofbe_data.core.front_door import lazy_names

_FRONT_DOOR = {
    "QC_DONE": "ofbe_data.freeliving.ggir",
    "QC_DONE_NO_TEMPERATURE": "ofbe_data.freeliving.ggir",
    "QC_MESSAGES": "ofbe_data.freeliving.ggir",
    "QC_NOT_DECREASED": "ofbe_data.freeliving.ggir",
    "QC_NOT_GOOD_ENOUGH": "ofbe_data.freeliving.ggir",
    "QC_NO_STILL": "ofbe_data.freeliving.ggir",
    "QC_SPHERE_NOT_POPULATED": "ofbe_data.freeliving.ggir",
    "QC_TOO_SHORT": "ofbe_data.freeliving.ggir",
    "BadBlock": "ofbe_data.freeliving.blocks",
    "EpochFileError": "ofbe_data.freeliving.epochs",
    "EpochTable": "ofbe_data.freeliving.epochs",
    "GgirResult": "ofbe_data.freeliving.ggir",
    "GgirSettings": "ofbe_data.freeliving.ggir",
    "IdleSleep": "ofbe_data.freeliving.raw",
    "OfbeResult": "ofbe_data.freeliving.ofbe",
    "OfbeSettings": "ofbe_data.freeliving.ofbe",
    "RawEpochs": "ofbe_data.freeliving.raw",
    "RawFileError": "ofbe_data.freeliving.blocks",
    "apply_ggir": "ofbe_data.freeliving.ggir",
    "fit_sphere": "ofbe_data.freeliving.ggir",
    "ggir_calibrate": "ofbe_data.freeliving.ggir",
    "idle_sleep": "ofbe_data.freeliving.epochs",
    "is_epoch_csv": "ofbe_data.freeliving.epochs",
    "ofbe_calibrate": "ofbe_data.freeliving.ofbe",
    "parse_epoch_csv": "ofbe_data.freeliving.epochs",
    "read_epoch_csv": "ofbe_data.freeliving.epochs",
    "read_raw_epochs": "ofbe_data.freeliving.raw",
}
"""Each name this package exports and the module that defines it (imported on first use, so that
importing one module of the package, :mod:`~ofbe_data.freeliving.ggir` for ``ofbe-autocal``'s
``--help``, does not import the others)."""

__all__ = [
    "QC_DONE",
    "QC_DONE_NO_TEMPERATURE",
    "QC_MESSAGES",
    "QC_NOT_DECREASED",
    "QC_NOT_GOOD_ENOUGH",
    "QC_NO_STILL",
    "QC_SPHERE_NOT_POPULATED",
    "QC_TOO_SHORT",
    "BadBlock",
    "EpochFileError",
    "EpochTable",
    "GgirResult",
    "GgirSettings",
    "IdleSleep",
    "OfbeResult",
    "OfbeSettings",
    "RawEpochs",
    "RawFileError",
    "apply_ggir",
    "fit_sphere",
    "ggir_calibrate",
    "idle_sleep",
    "is_epoch_csv",
    "ofbe_calibrate",
    "parse_epoch_csv",
    "read_epoch_csv",
    "read_raw_epochs",
]

__getattr__, __dir__ = lazy_names(__name__, _FRONT_DOOR)
