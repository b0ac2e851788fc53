"""The calibration formats of ``ofbe-export`` (:data:`CALIBRATION_FORMATS`): each a
:class:`~ofbe_data.calibration.registry.Format` whose handler turns the parsed command line into
the files to write, with its own options and examples.

SOURCE is a labels folder (``processed/labels/<campaign>``), one ``<session>.parquet``, the JSON
``ofbe-predict`` prints (:mod:`ofbe_data.calibration.results`), or, for ``ggir``, ``json`` and
``imucal``, an ``ofbe-autocal`` output folder (:mod:`ofbe_data.calibration.autocal`, recognised
by its ``summary.parquet``): one file per device and power cycle, per estimate, or per calibrated
recording (``ggir``: one file per run). The conversions are in
:mod:`ofbe_data.calibration.formats`; writing, ``--force`` and ``--store`` are shared
(:mod:`ofbe_data.calibration.output`).

:func:`export_formats` is the one registry of the command: these formats, then those other
packages register through the entry-point group (the model package's ``tflite`` and
``c-header``, :mod:`ofbe_data.calibration.registry`).

Building the parser imports nothing heavy: each format's handler is in
:mod:`~ofbe_data.calibration.handlers`, imported when the format runs; its options' defaults and
choices are in :mod:`~ofbe_data.calibration.defaults`.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from ofbe_data.calibration.defaults import (
    DEFAULT_FRAME_ID,
    DEFAULT_ROSTOPIC,
    GGIR_CONVENTIONS,
    GGIR_DATA,
    GGIR_DATA_README,
    ROS_NODE,
)
from ofbe_data.calibration.registry import ExportRegistryError, Format, Unavailable, plugin_formats
from ofbe_data.calibration.ros_names import ros_node_problem

if TYPE_CHECKING:
    from ofbe_data.calibration.output import ExportFile

__all__ = ["CALIBRATION_FORMATS", "GGIR_DATA", "GGIR_DATA_README", "export_formats", "export_names",
           "positive_number"]


def _ros_node(text: str) -> str:
    """``--ros-node``: a node key ROS 2's parameter-file parser accepts (:func:`ros_node_problem`)."""
    problem = ros_node_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{problem} (ROS 2 would refuse the file), found {text!r}")
    return text


# each handler is imported when its format runs (ofbe_data.calibration.handlers)


def _imucal(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import imucal_files

    return imucal_files(args)


def _kalibr(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import kalibr_files

    return kalibr_files(args)


def _ros(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import ros_files

    return ros_files(args)


def _ggir(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import ggir_files

    return ggir_files(args)


def _json(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.handlers import json_files

    return json_files(args)


def _ros_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frame-id", default=DEFAULT_FRAME_ID, help="the frame_id written")
    p.add_argument("--ros-node", default=ROS_NODE, type=_ros_node,
                   help="the node the parameters are for (the default, /**, is every node that loads the "
                        "file)")


def _ggir_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--g-convention", choices=GGIR_CONVENTIONS, default="unit-sphere",
                   help="unit-sphere: GGIR's (resting readings of norm 1 g); local: ofbe's (norm g_local/g0)")
    p.add_argument("--ggir-data", action="store_true",
                   help="also rebuild the raw files (from --raw) as clean CSV that GGIR's csv reader reads "
                        "whole, in OUT/ggir-data/ under the names of the filename column, with the rmc.* "
                        "settings in OUT/ggir-data.README.txt")


def _kalibr_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rostopic", default=DEFAULT_ROSTOPIC, help="the rostopic written")
    p.add_argument("--gyro-noise-density", type=positive_number, metavar="RAD_S_SQRT_HZ",
                   help="gyroscope white-noise density, rad/s/sqrt(Hz) (datasheet); when left out, measured "
                        "from the recordings' gyroscope columns")
    p.add_argument("--gyro-random-walk", type=positive_number, metavar="RAD_S2_SQRT_HZ",
                   help="gyroscope bias random walk, rad/s^2/sqrt(Hz); when left out, measured from the "
                        "gyroscope columns (or their flagged upper bound)")


def positive_number(text: str) -> float:
    """An option's value as a positive finite number (argparse's ``type``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}")
    return value


CALIBRATION_FORMATS: dict[str, Format] = {
    "imucal": Format(_imucal, "imucal Ferraris calibration JSON (accelerometer from ofbe, gyroscope "
                              "identity)",
                     examples=("ofbe-export imucal mine/labels/lab --out mine/cal/",
                               "ofbe-export imucal mine/labels/lab --store mine/cal-store",
                               "ofbe-export imucal mine/autocal --out mine/cal/   # an ofbe-autocal folder")),
    "kalibr": Format(_kalibr, "Kalibr imu.yaml: accelerometer and gyroscope noise density and random walk "
                              "from the Allan deviation (gyroscope from its columns or flags); needs --raw",
                     _kalibr_options,
                     ("ofbe-export kalibr processed/labels/rotated --raw raw/rotated --out mine/kalibr/",)),
    "ros": Format(_ros, "YAML: bias to subtract (m/s²) and linear_acceleration_covariance", _ros_options,
                  ("ofbe-export ros mine/labels/lab --out mine/ros/ --frame-id imu_link",)),
    "ggir": Format(_ggir, "GGIR backup.cal.coef CSV, one per run: scale.*, offset.* (g, GGIR's sign)",
                   _ggir_options,
                   ("ofbe-export ggir mine/labels/lab --out mine/ggir/",
                    "ofbe-export ggir mine/labels/lab --raw mine/raw/lab --ggir-data --out mine/ggir/",
                    "ofbe-export ggir mine/autocal --out mine/ggir/   # an ofbe-autocal folder")),
    "json": Format(_json, "ofbe-calibration/1 JSON: bias, std, kind, method, source, time, version",
                   examples=("ofbe-export json mine/labels/lab --out mine/json/",
                             "ofbe-export json predictions.json --out mine/json/   # ofbe-predict's output",
                             "ofbe-export json mine/autocal --out mine/json/   # an ofbe-autocal folder")),
}
"""FORMAT → how to export it: this package's calibration formats."""


def export_formats() -> tuple[dict[str, Format], dict[str, Unavailable]]:
    """Every format of ``ofbe-export``: :data:`CALIBRATION_FORMATS`, then those registered by
    other packages (:func:`ofbe_data.calibration.registry.plugin_formats`), and the registered
    ones that cannot be imported here.

    Raises
    ------
    ExportRegistryError
        A registered format is not a Format, or takes the name of a calibration format.
    """
    plugins, unavailable = plugin_formats()
    clash = sorted(set(plugins) & set(CALIBRATION_FORMATS))
    if clash:
        raise ExportRegistryError(f"entry points {', '.join(clash)}: expected new format names, found "
                                  "names of ofbe's calibration formats")
    return {**CALIBRATION_FORMATS, **plugins}, unavailable


def export_names() -> tuple[str, ...]:
    """The name of every format registered with ``ofbe-export``, those that cannot be imported
    here included (:func:`export_formats`)."""
    formats, unavailable = export_formats()
    return (*formats, *unavailable)
