"""``ofbe-export kalibr``: Kalibr's imu.yaml, noise densities and random walks from the Allan
deviation of the raw recordings; the files are made by
:func:`ofbe_data.calibration.handlers.kalibr_files`."""

from __future__ import annotations

import argparse
import math

from ofbe_data.calibration.defaults import DEFAULT_ROSTOPIC
from ofbe_data.calibration.registry import Format


def positive_number(text: str) -> float:
    """An option's value as a positive finite number (argparse's ``type``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}")
    return value


def _options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rostopic", default=DEFAULT_ROSTOPIC, help="the rostopic written")
    p.add_argument("--gyro-noise-density", type=positive_number, metavar="RAD_S_SQRT_HZ",
                   help="gyroscope white-noise density, rad/s/sqrt(Hz) (datasheet); when left out, measured "
                        "from the recordings' gyroscope columns")
    p.add_argument("--gyro-random-walk", type=positive_number, metavar="RAD_S2_SQRT_HZ",
                   help="gyroscope bias random walk, rad/s^2/sqrt(Hz); when left out, measured from the "
                        "gyroscope columns (or their flagged upper bound)")


FORMAT = Format(
    name="kalibr",
    order=20,
    handler="ofbe_data.calibration.handlers:kalibr_files",
    help=("Kalibr imu.yaml: accelerometer and gyroscope noise density and random walk from the Allan "
          "deviation (gyroscope from its columns or flags); needs --raw"),
    options=_options,
    examples=("ofbe-export kalibr processed/labels/rotated --raw raw/rotated --out mine/kalibr/",),
)
