"""QoS of the node's topics, and input subscriptions that serve reliable and best-effort
publishers alike (rclpy glue).

Inputs (``input_reliability``):

- ``best_available`` (default): rmw's BEST_AVAILABLE, resolved when the subscription is created
  against the publishers discovered by then (RELIABLE if they all are, which includes "none
  yet"). rmw does not resolve it again, so a best-effort publisher (sensor-data QoS, the usual
  choice of a simulator) that appears later would be refused as incompatible. The node listens
  for that event and subscribes again, which then resolves to BEST_EFFORT and serves both
  kinds. The handover loses nothing: the old subscription stays until the new one is matched
  with every publisher of the topic (at most ``HANDOVER_S``), a message that reached both is
  delivered once (same bytes; the new one's copy may come after the old one is gone, so its
  copies are looked for up to ``TAIL_S`` longer), and what is still queued in the old one is
  taken before it goes.
  ``resubscribed`` on /diagnostics counts the handovers, ``resubscribe_unmatched`` those that
  ended on the time bound with a publisher not yet matched (a possible loss: a warning).
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

from collections import Counter
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
from rclpy.qos import HistoryPolicy, QoSPolicyKind, QoSProfile, ReliabilityPolicy
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


HANDOVER_S = 2.0  # bound on waiting for the new subscription's matches (steady time)
POLL_S = 0.005  # how often the handover checks them
TAIL_S = 5.0  # how long the new subscription's late copies of the old one's messages are dropped


class Handover:
    """Two subscriptions on one topic for a moment: a message that reached both (the same
    bytes) is delivered once. Once the old one is gone (``closed``), the new one's copies of
    what the old one delivered are still dropped."""

    def __init__(self) -> None:
        self.pending: dict[str, Counter[bytes]] = {"old": Counter(), "new": Counter()}
        self.duplicates = 0
        self.closed = False

    def first(self, side: str, data: bytes) -> bool:
        """True if ``data`` from ``side`` ("old" or "new") has not come from the other side."""
        other = self.pending["new" if side == "old" else "old"]
        if other[data]:
            other[data] -= 1
            if not other[data]:
                del other[data]
            self.duplicates += 1
            return False
        if not self.closed:
            self.pending[side][data] += 1
        return True


class InputSubscription:
    """One input topic's subscription, subscribed again without loss when a publisher it
    cannot serve appears and the reliability is ``best_available`` (module docstring)."""

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
        self.unmatched = 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)  # not paused with sim time
        self._timer: Any = None
        self._handover: Handover | None = None
        self._deadline_ns = 0
        self._matched = False
        self._old: Subscription | None = None
        self.sub: Subscription | None = self._subscribe(callback)

    def _subscribe(self, callback: Callable[[bytes], None]) -> Subscription:
        events = SubscriptionEventCallbacks(incompatible_qos=self._on_incompatible)
        return self.node.create_subscription(
            self.msg_type, self.topic, callback, self.qos.inputs(), raw=True,
            event_callbacks=events,
        )  # fmt: skip

    def _on_incompatible(self, info: QoSRequestedIncompatibleQoSInfo) -> None:
        resolvable = info.last_policy_kind == QoSPolicyKind.RELIABILITY
        if self.qos.input_reliability != "best_available" or not resolvable:
            self.node.get_logger().warning(
                f"{self.topic}: a publisher with incompatible QoS is not served "
                f"(input_reliability {self.qos.input_reliability}; policy {info.last_policy_kind})"
            )
            return
        if self._timer is None and self._handover is None:  # on the executor, not in rmw's event
            self._timer = self.node.create_timer(0.0, self._begin_handover, clock=self._steady)

    def _begin_handover(self) -> None:
        """Subscribe again beside the old subscription; both deliver through the handover."""
        self.node.destroy_timer(self._timer)
        self._handover = Handover()
        self._old = self.sub
        if self._old is not None:
            self._old.callback = self._from_old
        self.sub = self._subscribe(self._from_new)
        self._deadline_ns = self._steady.now().nanoseconds + int(HANDOVER_S * 1e9)
        self._timer = self.node.create_timer(POLL_S, self._poll_handover, clock=self._steady)

    def _from_old(self, data: bytes) -> None:
        if self._handover is None or self._handover.first("old", data):
            self.callback(data)

    def _from_new(self, data: bytes) -> None:
        handover = self._handover
        if handover is None:
            self.callback(data)
            return
        if handover.first("new", data):
            self.callback(data)
        if handover.closed and not handover.pending["old"]:
            self._end_handover()  # every copy seen: no need to wait for TAIL_S

    def _poll_handover(self) -> None:
        """Close the handover once the new subscription is matched with every publisher."""
        assert self.sub is not None and self._handover is not None
        matched = self.sub.get_publisher_count() >= self.node.count_publishers(self.topic)
        late = self._steady.now().nanoseconds >= self._deadline_ns
        if not (matched or late):
            return
        self.node.destroy_timer(self._timer)
        self._drain_old()
        self._handover.closed = True
        self._handover.pending["new"].clear()  # nothing of the old one's is to come
        self.resubscribed += 1
        self.unmatched += 0 if matched else 1
        self._matched = matched
        self._timer = self.node.create_timer(TAIL_S, self._end_handover, clock=self._steady)

    def _end_handover(self) -> None:
        """Stop looking for copies; say how the handover went."""
        if self._handover is None:
            return
        self.node.destroy_timer(self._timer)
        self._timer = None
        log = self.node.get_logger()
        (log.info if self._matched else log.warning)(
            f"{self.topic}: a best-effort publisher appeared; subscribed again (best available "
            "now resolves to best effort: reliable and best-effort publishers are served); "
            + ("every publisher matched" if self._matched else f"NOT every publisher matched in "
               f"{HANDOVER_S} s: messages may be lost")
            + f", {self._handover.duplicates} message(s) that reached both delivered once"
        )  # fmt: skip
        self._handover = None

    def _drain_old(self) -> None:
        """Deliver what the old subscription still holds, then destroy it."""
        old, self._old = self._old, None
        if old is None:
            return
        with old.handle:
            while (taken := old.handle.take_message(old.msg_type, old.raw)) is not None:
                self._from_old(taken[0])
        self.node.destroy_subscription(old)

    def destroy(self) -> None:
        if self._timer is not None:
            self.node.destroy_timer(self._timer)
            self._timer = None
        for sub in (self._old, self.sub):
            if sub is not None:
                self.node.destroy_subscription(sub)
        self._old = self.sub = None


def output_events(node: Node, topic: str) -> PublisherEventCallbacks:
    """Log every change of the number of subscribers matched to an output topic."""

    def matched(info: QoSPublisherMatchedInfo) -> None:
        node.get_logger().info(f"{topic}: {info.current_count} subscriber(s) matched")

    return PublisherEventCallbacks(matched=matched)
