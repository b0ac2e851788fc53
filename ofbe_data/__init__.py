"""The data's journey from raw files to shareable datasets, in wings.

The front door (what a notebook needs; each name is imported on first use, so that
``import ofbe_data`` stays light):

>>> import ofbe_data as od
>>> session = od.load_manifest("raw/examples/tiny-multi-position/mp-pc001")  # session.yaml
>>> labels = od.label_session("raw/examples/tiny-multi-position/mp-pc001")   # 16 poses, 2 boards
>>> df = od.read_labels("processed/labels/rotated")                     # labels as pandas
>>> ds = od.load_dataset("processed/datasets/rotated")                  # windows, labels, folds

- reading: :func:`load_manifest` (a session's ``session.yaml``), :func:`read_device_file` (one
  device file as a typed ``Recording``), :func:`simulate_campaign` (a simulated campaign with
  its truth);
- labelling: :func:`label_session`, :class:`LabelParams`, :func:`load_label_params`,
  :func:`write_session`, :func:`read_labels`;
- datasets and calibrations: :func:`load_dataset`, :func:`verify_dataset`,
  :func:`find_calibration` (the calibration in force for a device at a time);
- free-living: :func:`read_epoch_csv`, :func:`ggir_calibrate` (GGIR's ``g.calibrate``).

The wings:

- :mod:`ofbe_data.core`: errors, atomic writes, precision, geometry, the worker pool, the
  figure style, the shared command-line pieces;
- :mod:`ofbe_data.io`: manifests, device formats (one module per format behind a registry),
  typed recordings, YAML and configuration, local gravity;
- :mod:`ofbe_data.simulator`: simulated campaigns with their truth;
- :mod:`ofbe_data.labelling`: synchronisation, stationarity, orientation, the pose and campaign
  fits, convergence, labels and the label files;
- :mod:`ofbe_data.dataset`: windows, leak-free splits, the dataset store, export;
- :mod:`ofbe_data.calibration`: calibration results and the other tools' formats;
- :mod:`ofbe_data.freeliving`: calibration of wearables from their own still periods;
- :mod:`ofbe_data.reports`: the convergence, small-angle and index reports;
- :mod:`ofbe_data.cli`: the data package's commands.

Data flows one way, raw files → recordings → labels → windows/splits → datasets; the import
rules are in docs/architecture.md and enforced by tests/test_architecture.py.
"""

from __future__ import annotations

from ofbe_data.core.front_door import lazy_names

__version__ = "0.1.0"

_FRONT_DOOR = {
    "load_manifest": "ofbe_data.io.manifest",
    "read_device_file": "ofbe_data.io.formats",
    "simulate_campaign": "ofbe_data.simulator",
    "label_session": "ofbe_data.labelling.labels",
    "LabelParams": "ofbe_data.labelling.labels",
    "load_label_params": "ofbe_data.labelling.labels",
    "write_session": "ofbe_data.labelling.store",
    "read_labels": "ofbe_data.labelling.store",
    "load_dataset": "ofbe_data.dataset.reader",
    "verify_dataset": "ofbe_data.dataset.reader",
    "find_calibration": "ofbe_data.calibration.store",
    "read_epoch_csv": "ofbe_data.freeliving",
    "ggir_calibrate": "ofbe_data.freeliving",
}
"""Each front-door name and the module that defines it (imported on first use)."""

__all__ = ["__version__", *sorted(_FRONT_DOOR)]

__getattr__, __dir__ = lazy_names(__name__, _FRONT_DOOR)
