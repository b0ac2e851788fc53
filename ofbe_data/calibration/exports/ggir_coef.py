"""``ofbe-export ggir``: GGIR's backup.cal.coef CSV, one row per run (scale.*, offset.* in g, GGIR's
sign), and on request the raw files rebuilt as CSV that GGIR's reader takes whole; the files are
made by :func:`ofbe_data.calibration.handlers.ggir_files`."""

from __future__ import annotations

import argparse

from ofbe_data.calibration.defaults import GGIR_CONVENTIONS
from ofbe_data.calibration.registry import Format


def _options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--g-convention", choices=GGIR_CONVENTIONS, default="unit-sphere",
                   help="unit-sphere: GGIR's (resting readings of norm 1 g); local: ofbe's (norm g_local/g0)")
    p.add_argument("--ggir-data", action="store_true",
                   help="also rebuild the raw files (from --raw) as clean CSV that GGIR's csv reader reads "
                        "whole, in OUT/ggir-data/ under the names of the filename column, with the rmc.* "
                        "settings in OUT/ggir-data.README.txt")


FORMAT = Format(
    name="ggir",
    order=40,
    handler="ofbe_data.calibration.handlers:ggir_files",
    help="GGIR backup.cal.coef CSV, one per run: scale.*, offset.* (g, GGIR's sign)",
    options=_options,
    examples=(
        "ofbe-export ggir mine/labels/lab --out mine/ggir/",
        "ofbe-export ggir mine/labels/lab --raw mine/raw/lab --ggir-data --out mine/ggir/",
        "ofbe-export ggir mine/autocal --out mine/ggir/   # an ofbe-autocal folder",
    ),
)
