"""ROS 2 node keys of a parameter file, as rcl's parser validates them (rcl_yaml_param_parser
src/parse.c ``__validate_name``, with rmw's node-name and namespace rules)."""

from __future__ import annotations

import pytest

from ofbe_data.calibration.ros_names import ros_node_problem
from ofbe_data.cli.export import main as export_main


@pytest.mark.parametrize("name", ["/**", "imu", "imu_node_2", "_x", "/imu", "/ns/imu", "ns/imu", "/a/b/c",
                                  "/**/imu", "/ns/*", "*"])
def test_names_rcl_accepts(name: str) -> None:
    assert ros_node_problem(name) is None


@pytest.mark.parametrize("name, problem", [
    ("", "expected a node name"),
    ("/", "expected a node name after the namespace"),
    ("imu/", "expected a node name after the namespace"),
    ("/my node!", "node name 'my node!': expected letters, digits and underscores (at most 255), not "
                  "starting with a digit"),
    ("1imu", "node name '1imu': expected letters, digits and underscores (at most 255), not starting "
             "with a digit"),
    ("x" * 256, f"node name '{'x' * 256}': expected letters, digits and underscores (at most 255), not "
                "starting with a digit"),
    ("/ns//imu", "namespace '/ns/': expected '/'-separated names of letters, digits and underscores, none "
                 "empty or starting with a digit"),
    ("/9ns/imu", "namespace '/9ns': expected '/'-separated names of letters, digits and underscores, none "
                 "empty or starting with a digit"),
    ("~/imu", "namespace '/~': expected '/'-separated names of letters, digits and underscores, none empty "
              "or starting with a digit")])
def test_names_rcl_refuses(name: str, problem: str) -> None:
    assert ros_node_problem(name) == problem


def test_the_export_refuses_such_a_name_before_writing(tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as info:
        export_main(["ros", str(tmp_path / "labels"), "--out", str(tmp_path / "out"),
                     "--ros-node", "/my node!"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == ("ofbe-export ros: error: argument --ros-node: node name 'my node!': expected letters, "
                   "digits and underscores (at most 255), not starting with a digit (ROS 2 would refuse the "
                   "file), found '/my node!'")
    assert not (tmp_path / "out").exists()
