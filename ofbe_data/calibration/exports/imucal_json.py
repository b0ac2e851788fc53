"""``ofbe-export imucal``: imucal's Ferraris calibration JSON (the accelerometer's from ofbe, the
gyroscope's identity); the files are made by :func:`ofbe_data.calibration.handlers.imucal_files`."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ofbe_data.calibration.registry import Format

if TYPE_CHECKING:
    from ofbe_data.calibration.output import ExportFile


def _files(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import imucal_files

    return imucal_files(args)


FORMAT = Format(_files, "imucal Ferraris calibration JSON (accelerometer from ofbe, gyroscope identity)",
                examples=("ofbe-export imucal mine/labels/lab --out mine/cal/",
                          "ofbe-export imucal mine/labels/lab --store mine/cal-store",
                          "ofbe-export imucal mine/autocal --out mine/cal/   # an ofbe-autocal folder"),
                name="imucal", order=10)
