"""``tire_model_lifecycle_node``: the node as a managed (lifecycle) node, for a launch system or
simulator that configures, activates and deactivates it (``rclpy.lifecycle``; ROS glue).

Console scripts ``tire-model-lifecycle-node`` and ``tire_model_lifecycle_node`` (``ros2 run
tire_model_ros tire_model_lifecycle_node``); node name ``tire_model_node`` as the plain node,
the same parameters and topics (:mod:`.node`). Transitions (``ros2 lifecycle set``, or the
``~/change_state`` service):

- configure: reads the parameters, loads the .tir (and effects) files, declares the coefficient
  parameters, creates the topics, ``~/reload`` and /diagnostics. A file that cannot be loaded
  fails the transition (the node stays unconfigured and says why).
- activate: slip messages are answered from now on.
- deactivate: the slips held for their inputs (``align.wait``) are answered with what there
  is; slip messages are no longer answered, each one that arrives is counted in
  ``slip_inactive`` (inputs are still taken, so the next activation starts with fresh ones).
- cleanup: undoes configure (topics, coefficient parameters and models gone).
- shutdown (from any state): undoes what is set up, and the process exits with status 0.

Before configure, parameters may be set freely (files are only read at configure).
"""

from __future__ import annotations

import sys
from typing import Any

import rclpy
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from tire_model_ros.ros.node import NODE_NAME, START_ERRORS, TireModelCore, run


class TireModelLifecycleNode(TireModelCore, LifecycleNode):
    """The managed form of the node (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        LifecycleNode.__init__(self, NODE_NAME, **kwargs)
        self._init_core()
        self.finished = False

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self._setup()
        except START_ERRORS as exc:
            self.get_logger().error(f"configure failed: {exc}")
            self._teardown()
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = True
        self.get_logger().info("active: answering slip messages")
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.flush_held()  # the slips waiting for their inputs are answered now
        self.active = False
        self.get_logger().info("inactive: slip messages are counted, not answered")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        if self.configured:
            self._teardown()
        self.finished = True
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        if self.configured:
            self._teardown()
        return TransitionCallbackReturn.SUCCESS


def main(args: list[str] | None = None) -> int:
    """Console entry point: run until SIGINT/SIGTERM or the shutdown transition."""
    rclpy.init(args=args)
    return run(TireModelLifecycleNode, lambda node: bool(node.finished))


if __name__ == "__main__":
    sys.exit(main())
