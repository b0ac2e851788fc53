"""Calibration results in the formats other tools load, and a store of them by device and time.

- :mod:`~ofbe_data.calibration.results`: one result per (device, power cycle) of a labels
  folder, or per estimate of an ``ofbe-predict`` JSON: the bias b (zero-g offset or apparent
  bias) of ``f = A·u·g + b``, its std, where it came from and when it was recorded;
- :mod:`~ofbe_data.calibration.noise`: the raw recordings behind the labels (start times,
  stationary segments) and their Allan noise density for Kalibr;
- :mod:`~ofbe_data.calibration.formats`: one small function per format that converts ofbe's
  sign and unit convention, and the writers (imucal, Kalibr, ROS, GGIR, ofbe JSON);
- :mod:`~ofbe_data.calibration.autocal`: the results of an ``ofbe-autocal`` folder and their
  GGIR, JSON and imucal files;
- :mod:`~ofbe_data.calibration.store`: ``DIR/<device>/<device>_<time>.<ending>`` and
  :func:`~ofbe_data.calibration.store.find_calibration`;
- :mod:`~ofbe_data.calibration.registry`: what a format of ``ofbe-export`` is, and the
  entry-point group other packages register formats in;
  :mod:`~ofbe_data.calibration.exports`: the calibration formats and the one registry (light:
  names, help, options and examples; their defaults in :mod:`~ofbe_data.calibration.defaults`);
  :mod:`~ofbe_data.calibration.handlers`: what each calibration format does when it runs;
  :mod:`~ofbe_data.calibration.output`: writing an export's files.

The command is ``ofbe-export`` (:mod:`ofbe_data.cli.export`; the model package registers
``tflite`` and ``c-header`` through the entry point). This package may import
:mod:`ofbe_data.core`, :mod:`ofbe_data.io`, :mod:`ofbe_data.labelling` (label files, Allan
deviation) and :mod:`ofbe_data.freeliving` (the autocal summary's columns); never
:mod:`ofbe_model`.
docs/exports.md derives every convention.
"""
