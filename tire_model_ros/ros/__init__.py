"""Everything of this package that needs ROS 2 (rclpy, message packages) at run time.

The rest of ``tire_model_ros`` (model, recording I/O, rig, fit, diagnosis, the per-wheel logic
of the node in :mod:`tire_model_ros.wheel`, the offline commands) imports no ROS module and
works from a plain ``pip install``. Here: the node (:mod:`.node`), ``play`` and ``record``, the
teardown deadline of those processes, their CDR fast path and latency settings.

This ``__init__`` imports nothing from ROS, so a command can ask :func:`require_ros` first and
tell the user what is missing instead of failing with a traceback.
"""

from __future__ import annotations

import importlib
import sys


class RosUnavailableError(RuntimeError):
    """ROS 2 (rclpy) cannot be imported; the message names the command that needs it."""


def require_ros(what: str) -> None:
    """Raise :class:`RosUnavailableError` naming ``what`` when rclpy cannot be imported."""
    try:
        importlib.import_module("rclpy")
    except ImportError as exc:
        raise RosUnavailableError(
            f"{what} needs ROS 2 Jazzy (rclpy), which cannot be imported here ({exc}); "
            "source /opt/ros/jazzy/setup.bash or use the project's .venv"
        ) from None


def _entry(command: str, module: str, args: list[str] | None) -> int:
    """Run ``module``'s ``main`` when ROS 2 can be imported, else say what is missing (exit 1)."""
    try:
        require_ros(command)
    except RosUnavailableError as exc:
        print(f"{command}: error: {exc}", file=sys.stderr)
        return 1
    main = importlib.import_module(module).main
    code: int = main(args)
    return code


def node_main(args: list[str] | None = None) -> int:
    """Console entry point of ``tire-model-node`` (:func:`tire_model_ros.ros.node.main`)."""
    return _entry("tire-model-node", "tire_model_ros.ros.node", args)


def lifecycle_main(args: list[str] | None = None) -> int:
    """Console entry point of ``tire-model-lifecycle-node`` (:mod:`.lifecycle`'s ``main``)."""
    return _entry("tire-model-lifecycle-node", "tire_model_ros.ros.lifecycle", args)
