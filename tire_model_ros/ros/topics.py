"""QoS of the node's topics, and input subscriptions that serve reliable and best-effort
publishers alike (rclpy glue).

Inputs (``input_reliability``):

- ``best_available`` (default): rmw's BEST_AVAILABLE, resolved when the subscription is created
  against the publishers discovered by then (RELIABLE if they all are, which includes "none
  yet"). rmw does not resolve it again, so a best-effort publisher (sensor-data QoS, the usual
  choice of a simulator) that appears later would be refused as incompatible. The node listens
  for that event and subscribes again, which then resolves to BEST_EFFORT and serves both
  kinds. Messages still queued in the old subscription at that moment are lost (once per topic,
  when the first best-effort publisher appears; counted in ``resubscribed`` on /diagnostics).
- ``reliable``: only reliable publishers are served (an incompatible one is logged).
- ``best_effort``: every publisher is served, none reliably.

``input_history``: ``keep_all`` (default) keeps every message until the node has taken it, so a
reliable publisher is held back (DDS flow control) instead of losing messages when the node
falls behind; ``keep_last`` keeps the newest ``qos_depth``.

Output (``output_reliability``): ``reliable`` (default) or ``best_effort``, history keep-last
``qos_depth``. The node logs each change of the number of subscribers matched to ``P/forces``
(so a launcher or test can wait for the recorder before playing).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import (
    PublisherEventCallbacks,
    QoSPublisherMatchedInfo,
    QoSRequestedIncompatibleQoSInfo,
    SubscriptionEventCallbacks,
)
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

INPUT_RELIABILITY = {
    "best_available": ReliabilityPolicy.BEST_AVAILABLE,
    "reliable": ReliabilityPolicy.RELIABLE,
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
}
OUTPUT_RELIABILITY = {
    "reliable": ReliabilityPolicy.RELIABLE,
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
}
INPUT_HISTORY = {"keep_all": HistoryPolicy.KEEP_ALL, "keep_last": HistoryPolicy.KEEP_LAST}


def choice(name: str, value: object, options: dict[str, Any]) -> Any:
    """The policy a string parameter names; ValueError naming the parameter otherwise."""
    if value not in options:
        raise ValueError(f"{name}: {value!r} is not one of {', '.join(options)}")
    return options[str(value)]


@dataclass(frozen=True)
class TopicQoS:
    """The node's QoS settings (its read-only parameters)."""

    input_reliability: str = "best_available"
    input_history: str = "keep_all"
    output_reliability: str = "reliable"
    depth: int = 100

    def __post_init__(self) -> None:
        choice("input_reliability", self.input_reliability, INPUT_RELIABILITY)
        choice("input_history", self.input_history, INPUT_HISTORY)
        choice("output_reliability", self.output_reliability, OUTPUT_RELIABILITY)
        if self.depth < 1:
            raise ValueError(f"qos_depth: must be >= 1, got {self.depth}")

    def inputs(self) -> QoSProfile:
        return QoSProfile(
            history=INPUT_HISTORY[self.input_history],
            depth=self.depth,
            reliability=INPUT_RELIABILITY[self.input_reliability],
        )

    def output(self) -> QoSProfile:
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=self.depth,
            reliability=OUTPUT_RELIABILITY[self.output_reliability],
        )


class InputSubscription:
    """One input topic's subscription, subscribed again when a publisher it cannot serve
    appears and the reliability is ``best_available`` (module docstring)."""

    def __init__(
        self,
        node: Node,
        msg_type: type,
        topic: str,
        callback: Callable[[bytes], None],
        qos: TopicQoS,
    ) -> None:
        self.node = node
        self.msg_type = msg_type
        self.topic = topic
        self.callback = callback
        self.qos = qos
        self.resubscribed = 0
        self.incompatible = 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)  # not paused with sim time
        self._timer: Any = None
        self.sub: Subscription | None = None
        self._subscribe()

    def _subscribe(self) -> None:
        events = SubscriptionEventCallbacks(incompatible_qos=self._on_incompatible)
        self.sub = self.node.create_subscription(
            self.msg_type, self.topic, self.callback, self.qos.inputs(), raw=True,
            event_callbacks=events,
        )  # fmt: skip

    def _on_incompatible(self, info: QoSRequestedIncompatibleQoSInfo) -> None:
        self.incompatible += 1
        if self.qos.input_reliability != "best_available":
            self.node.get_logger().warning(
                f"{self.topic}: a publisher with incompatible QoS is not served "
                f"(input_reliability {self.qos.input_reliability}; policy {info.last_policy_kind})"
            )
            return
        if self._timer is None:  # not inside rmw's event: on the executor, once
            self._timer = self.node.create_timer(0.0, self._resubscribe, clock=self._steady)

    def _resubscribe(self) -> None:
        self.node.destroy_timer(self._timer)
        self._timer = None
        self.destroy()
        self._subscribe()
        self.resubscribed += 1
        self.node.get_logger().info(
            f"{self.topic}: a best-effort publisher appeared; subscribed again (best available "
            "now resolves to best effort: reliable and best-effort publishers are served)"
        )

    def destroy(self) -> None:
        if self.sub is not None:
            self.node.destroy_subscription(self.sub)
            self.sub = None


def output_events(node: Node, topic: str) -> PublisherEventCallbacks:
    """Log every change of the number of subscribers matched to an output topic."""

    def matched(info: QoSPublisherMatchedInfo) -> None:
        node.get_logger().info(f"{topic}: {info.current_count} subscriber(s) matched")

    return PublisherEventCallbacks(matched=matched)
