"""The estimators on ESP32-class devices: exports a microcontroller can run.

- :mod:`~ofbe_model.deploy.tflite`: OFBENet as TensorFlow Lite, float32 (raw m/s² in, m/s²
  out) and full-integer int8 (with a representative set), plus a JSON sidecar of the input
  scaling and quantisation (:func:`~ofbe_model.deploy.tflite.export_tflite`);
- :mod:`~ofbe_model.deploy.c_header`: the ``gravity-prior`` estimator as a self-contained C99
  header with a reference C function (:func:`~ofbe_model.deploy.c_header.export_c_header`).

Neither module is imported here, so importing this package does not start TensorFlow. It
may import ``ofbe_data`` (not its command lines), the estimators and OFBENet; the LiteRT
interpreter (``ai-edge-litert``, a dev extra) only where a model is run, never to export.
"""

from __future__ import annotations
