"""``tire_model_node``: streams each wheel's forces from the extended Magic Formula.

The ROS glue lives in :mod:`tire_model_ros.node.ros_node`; the ROS-free parts (per-wheel input
state and counters, parameter naming, .tir path resolution) in :mod:`.wheel` and
:mod:`.params`, so they import and test without rclpy.
"""

from __future__ import annotations


def main(args: list[str] | None = None) -> int:
    """Console entry point (``tire-model-node``, ``ros2 run tire_model_ros tire_model_node``)."""
    import sys

    from tire_model_ros.node.ros_node import main as ros_main

    code = ros_main(args)
    if args is None:
        sys.exit(code)
    return code
