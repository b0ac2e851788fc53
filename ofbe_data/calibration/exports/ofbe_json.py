"""``ofbe-export json``: ofbe's own calibration JSON (``ofbe-calibration/1``: bias, standard
deviation, kind, method, source, time, version); the files are made by
:func:`ofbe_data.calibration.handlers.json_files`."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ofbe_data.calibration.registry import Format

if TYPE_CHECKING:
    from ofbe_data.calibration.output import ExportFile


def _files(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import json_files

    return json_files(args)


FORMAT = Format(_files, "ofbe-calibration/1 JSON: bias, std, kind, method, source, time, version",
                examples=("ofbe-export json mine/labels/lab --out mine/json/",
                          "ofbe-export json predictions.json --out mine/json/   # ofbe-predict's output",
                          "ofbe-export json mine/autocal --out mine/json/   # an ofbe-autocal folder"),
                name="json", order=50)
