"""``ofbe-export ros``: a ROS 2 parameter file, the bias to subtract (m/s²) and the
linear-acceleration covariance; the files are made by
:func:`ofbe_data.calibration.handlers.ros_files`."""

from __future__ import annotations

import argparse

from ofbe_data.calibration.defaults import DEFAULT_FRAME_ID, ROS_NODE
from ofbe_data.calibration.registry import Format
from ofbe_data.calibration.ros_names import ros_node_problem


def _ros_node(text: str) -> str:
    """``--ros-node``: a node key ROS 2's parameter-file parser accepts (:func:`ros_node_problem`)."""
    problem = ros_node_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{problem} (ROS 2 would refuse the file), found {text!r}")
    return text


def _options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frame-id", default=DEFAULT_FRAME_ID, help="the frame_id written")
    p.add_argument("--ros-node", default=ROS_NODE, type=_ros_node,
                   help="the node the parameters are for (the default, /**, is every node that loads the "
                        "file)")


FORMAT = Format(
    name="ros",
    order=30,
    handler="ofbe_data.calibration.handlers:ros_files",
    help="YAML: bias to subtract (m/s²) and linear_acceleration_covariance",
    options=_options,
    examples=("ofbe-export ros mine/labels/lab --out mine/ros/ --frame-id imu_link",),
)
