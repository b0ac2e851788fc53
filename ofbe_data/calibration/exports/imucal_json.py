"""``ofbe-export imucal``: imucal's Ferraris calibration JSON (the accelerometer's from ofbe, the
gyroscope's identity); the files are made by :func:`ofbe_data.calibration.handlers.imucal_files`."""

from __future__ import annotations

from ofbe_data.calibration.registry import Format

FORMAT = Format(
    name="imucal",
    order=10,
    handler="ofbe_data.calibration.handlers:imucal_files",
    help="imucal Ferraris calibration JSON (accelerometer from ofbe, gyroscope identity)",
    examples=(
        "ofbe-export imucal mine/labels/lab --out mine/cal/",
        "ofbe-export imucal mine/labels/lab --store mine/cal-store",
        "ofbe-export imucal mine/autocal --out mine/cal/   # an ofbe-autocal folder",
    ),
)
