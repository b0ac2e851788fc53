"""Names ROS 2 accepts as the node key of a parameter file (``ofbe-export ros --ros-node``).

A file whose node key rcl refuses is never loaded (``--ros-args --params-file`` fails), so the
export refuses such a name before writing.
"""

from __future__ import annotations

import re

_ROS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def ros_node_problem(name: str) -> str | None:
    """Why ROS 2 would refuse ``name`` as the node key of a parameter file, or None.

    Follows rcl's parameter-file parser (ros2/rcl, rcl_yaml_param_parser/src/parse.c,
    ``__validate_name``): ``/**`` is accepted as is; otherwise the name is split at its last
    ``/`` into a namespace (made absolute; ``/**`` accepted as is, else rmw's namespace rule:
    ``/``-separated tokens) and a node name (``*`` accepted, else rmw's node-name rule). A token
    and a node name are letters, digits and underscores, not starting with a digit (rmw's
    ``rmw_validate_node_name`` / ``rmw_validate_namespace``); a node name is at most 255
    characters.
    """
    if name == "/**":
        return None
    ns, sep, node = name.rpartition("/")
    if sep:
        ns = ns if ns.startswith("/") else "/" + ns
        tokens = ns[1:].split("/") if ns != "/" else []
        if ns != "/**" and not all(_ROS_TOKEN.fullmatch(t) for t in tokens):
            return (f"namespace {ns!r}: expected '/'-separated names of letters, digits and underscores, "
                    "none empty or starting with a digit")
    if node == "*":
        return None
    if not node:
        return "expected a node name after the namespace" if sep else "expected a node name"
    if not _ROS_TOKEN.fullmatch(node) or len(node) > 255:
        return (f"node name {node!r}: expected letters, digits and underscores (at most 255), not starting "
                "with a digit")
    return None
