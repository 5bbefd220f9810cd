"""The node's per-wheel logic without ROS: input state, staleness and counters
(:mod:`.state`), parameter names, ranges and .tir path resolution (:mod:`.params`).

The ROS glue that drives them is :mod:`tire_model_ros.ros.node`; these import and test without
rclpy.
"""
