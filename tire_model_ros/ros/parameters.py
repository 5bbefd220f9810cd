"""The node's own parameters and the coefficient descriptors (rclpy glue; names and ranges
come from :mod:`tire_model_ros.wheel.params` and the model's parameter table)."""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from tire_model_ros.ros import realtime
from tire_model_ros.ros.topics import INPUT_HISTORY, INPUT_RELIABILITY, OUTPUT_RELIABILITY
from tire_model_ros.vocabulary import STANDARD_ATMOSPHERE_PA
from tire_model_ros.wheel import params as pn


def descriptor(description: str, *, read_only: bool = False, **kw: Any) -> ParameterDescriptor:
    return ParameterDescriptor(description=description, read_only=read_only, **kw)


def _one_of(description: str, options: object) -> ParameterDescriptor:
    words = ", ".join(str(o) for o in options)  # type: ignore[attr-defined]
    return descriptor(f"{description}; one of {words}", read_only=True,
                      additional_constraints=f"one of: {words}")  # fmt: skip


def declare_node_params(node: Node) -> None:
    """Every parameter of the node but the coefficients (declared per loaded model)."""
    nonneg = FloatingPointRange(from_value=0.0, to_value=86400.0, step=0.0)
    d = node.declare_parameter
    d("wheels", ["wheel"], descriptor("wheel topic prefixes", read_only=True))
    d("tir_file", pn.default_tir_path(),
      descriptor("shared .tir file (absolute, relative to cwd, or to config/)"))  # fmt: skip
    d("lenient", False, descriptor(
        "read .tir files leniently: fill what a file's version needs and lacks with the "
        "documented defaults (listed in the log and on /diagnostics)"))  # fmt: skip
    d("effects_file", "",
      descriptor("effects file of `tire-model diagnose` (hidden states; '' = none)"))  # fmt: skip
    d("limits", True, descriptor("saturate inputs to the file's ranges, low-speed model"))
    d("pressure_is_absolute", False,
      descriptor("P/pressure is absolute (gauge = value - ambient_pressure)"))  # fmt: skip
    d("ambient_pressure", STANDARD_ATMOSPHERE_PA, descriptor(
        "ambient pressure [Pa] for pressure_is_absolute",
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=2e5)]))  # fmt: skip
    d("missing_load", "nominal", descriptor(
        "load missing or stale: 'nominal' = use FNOMIN, 'skip' = publish nothing",
        additional_constraints="one of: nominal, skip"))  # fmt: skip
    for name, value in pn.DEFAULT_TIMEOUTS.items():
        d(f"timeout.{name}", value, descriptor(
            f"{name} stamped more than this [s] before the slip -> nominal value; 0 = never stale",
            floating_point_range=[nonneg]))  # fmt: skip
    d("align.wait", pn.DEFAULT_ALIGN_WAIT, descriptor(
        "hold a slip until every input still arriving has a value stamped at or after it, at "
        "most this long [s] on the ROS clock; 0 = answer each slip on arrival",
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=pn.MAX_ALIGN_WAIT,
                                                 step=0.0)]))  # fmt: skip
    d("diagnostics_period", 1.0,
      descriptor("/diagnostics period [s] on the ROS clock", read_only=True))  # fmt: skip
    d("qos_depth", 100, descriptor("depth of the keep-last topic queues", read_only=True))
    d("input_reliability", "best_available",
      _one_of("reliability of the input subscriptions", INPUT_RELIABILITY))  # fmt: skip
    d("input_history", "keep_all", _one_of("history of the input subscriptions", INPUT_HISTORY))
    d("output_reliability", "reliable",
      _one_of("reliability of the P/forces publishers", OUTPUT_RELIABILITY))  # fmt: skip
    d("rt_priority", 0, descriptor(
        "SCHED_FIFO priority of the node's threads (1..99, needs root/CAP_SYS_NICE); "
        "0 = normal scheduling", read_only=True,
        integer_range=[IntegerRange(from_value=0, to_value=realtime.MAX_RT_PRIORITY)]))  # fmt: skip
    d("cpus", Parameter.Type.INTEGER_ARRAY,
      descriptor("CPUs the node's threads may run on; unset = all", read_only=True))  # fmt: skip


def coefficient_descriptor(key: str, value: float) -> ParameterDescriptor:
    """Description with units and the coefficient's range (every coefficient has one: from
    the physics where it sets one, else a sanity bound; a file outside it keeps no range)."""
    d = descriptor(pn.coefficient_description(key), dynamic_typing=True)
    d.type = ParameterType.PARAMETER_DOUBLE
    rng = pn.coefficient_range(key)
    if rng is not None and rng[0] <= value <= rng[1]:
        # Closed range for ROS; a strict minimum (e.g. FNOMIN > 0) is enforced on set.
        d.floating_point_range = [FloatingPointRange(from_value=rng[0], to_value=rng[1], step=0.0)]
        d.additional_constraints = f"{'>' if rng[2] else '>='} {rng[0]:g}, <= {rng[1]:g}"
    return d
