"""``ofbe-export json``: ofbe's own calibration JSON (``ofbe-calibration/1``: bias, standard
deviation, kind, method, source, time, version); the files are made by
:func:`ofbe_data.calibration.handlers.json_files`."""

from __future__ import annotations

from ofbe_data.calibration.registry import Format

FORMAT = Format(
    name="json",
    order=50,
    handler="ofbe_data.calibration.handlers:json_files",
    help="ofbe-calibration/1 JSON: bias, std, kind, method, source, time, version",
    examples=(
        "ofbe-export json mine/labels/lab --out mine/json/",
        "ofbe-export json predictions.json --out mine/json/   # ofbe-predict's output",
        "ofbe-export json mine/autocal --out mine/json/   # an ofbe-autocal folder",
    ),
)
