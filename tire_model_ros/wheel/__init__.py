"""The node's per-wheel logic without ROS: input state, counters and the computation of one
slip sample (:mod:`.state`), the inputs' stamped histories (:mod:`.history`, the offline
tool's alignment rule), their ranges and saturation (:mod:`.ranges`), parameter names, ranges
and .tir path resolution (:mod:`.params`).

The ROS glue that drives them is :mod:`tire_model_ros.ros.node`; these import and test without
rclpy.
"""
