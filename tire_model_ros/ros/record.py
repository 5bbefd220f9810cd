"""Record topics (the node's ``P/forces``, or any INTERFACE topic) to a new bag (rclpy glue).

Messages are taken as serialized CDR bytes (no deserialisation), logged with their
header.stamp as log time, and streamed into a ``BagWriter`` in a temp folder beside the
target; the bag is renamed into place when recording stops (SIGINT/SIGTERM, ``duration``,
``count``), so an interrupted recorder never leaves a half-written bag under the target name.

No silent loss: the subscriptions keep every message until taken (reliable, keep-all), and
the recorder counts per topic what it did not get: gaps in the publisher's sequence numbers
(a message the publisher dropped, or sent before the recorder was matched), and messages
ignored after ``count``; one ``record report`` line per topic says so
(:mod:`tire_model_ros.delivery`).
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Mapping, Sequence
from types import FrameType
from typing import Any

import numpy as np

from tire_model_ros.delivery import RECORD, report_line
from tire_model_ros.recording import BagWriter, cdr
from tire_model_ros.ros.msg_types import msg_class
from tire_model_ros.ros.teardown import deadline
from tire_model_ros.vocabulary import CHANNEL_TYPES, FORCES


def resolve_topics(topics: Sequence[str] = (), wheels: Sequence[str] = ()) -> dict[str, str]:
    """topic -> message type. ``TOPIC`` must end with an INTERFACE channel name
    (slip, load, pressure, temperature, velocity, forces, measured_forces); ``TOPIC:TYPE``
    gives the type explicitly. A wheel prefix P records ``P/forces``."""
    out: dict[str, str] = {}
    for prefix in wheels:
        out[f"{prefix.rstrip('/')}/{FORCES}"] = CHANNEL_TYPES[FORCES]
    for spec in topics:
        topic, _, msgtype = spec.partition(":")
        if not msgtype:
            channel = topic.rpartition("/")[2]
            if channel not in CHANNEL_TYPES:
                raise ValueError(
                    f"topic {topic}: unknown type (not an INTERFACE channel "
                    f"{', '.join(CHANNEL_TYPES)}); give it as TOPIC:pkg/msg/Type"
                )
            msgtype = CHANNEL_TYPES[channel]
        if not topic.startswith("/"):
            raise ValueError(f"topic {topic}: give absolute topic names (starting with '/')")
        out[topic] = msgtype
    if not out:
        raise ValueError("nothing to record: give --topics and/or --wheels")
    return out


def _stamp_ns(data: bytes, fallback_ns: int) -> int:
    """Header stamp of a CDR_LE message starting with std_msgs/Header, else ``fallback_ns``."""
    if len(data) >= 12 and data[1] == 1:
        buf = np.frombuffer(data, np.uint8)
        return int(cdr.header_stamps(buf, np.zeros(1, np.int64))[0])
    return fallback_ns


class TopicCount:
    """What the recorder got of one topic: recorded, missing (sequence gaps), ignored."""

    def __init__(self) -> None:
        self.recorded = 0
        self.gaps = 0
        self.ignored = 0
        self.publishers_seen = 0
        self._last_seq = 0

    def seen(self, seq: int | None) -> None:
        """One message with the publisher's sequence number (None: the rmw gives none)."""
        if seq is None:
            return
        if seq <= self._last_seq or self.publishers_seen == 0:
            self.publishers_seen += 1  # another (or a restarted) publisher: its count restarts
            self.gaps += seq - 1  # sent before this recorder was matched
        else:
            self.gaps += seq - self._last_seq - 1
        self._last_seq = seq

    def counts(self) -> dict[str, int]:
        return {"recorded": self.recorded, "gaps": self.gaps, "ignored": self.ignored,
                "publishers_seen": self.publishers_seen}  # fmt: skip


def record(
    out: str | os.PathLike[str],
    topics: Mapping[str, str],
    *,
    duration_s: float | None = None,
    count: int | None = None,
    overwrite: bool = False,
    storage: str = "mcap",
    queue: int = 1000,
    log: Callable[[str], None] = print,
) -> dict[str, int]:
    """Record until SIGINT/SIGTERM, ``duration_s`` seconds, or ``count`` messages in total.

    Returns messages recorded per topic. The bag is closed and renamed into place in every
    one of these cases, and on an unexpected error too (what was recorded is kept). ``log``
    gets one ``record report`` line per topic at the end (what was recorded, missing, ignored).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    if count is not None and count <= 0:
        raise ValueError(f"--count must be positive, got {count}")
    if duration_s is not None and not duration_s > 0:
        raise ValueError(f"--duration must be positive, got {duration_s}")
    classes = {}
    for topic, msgtype in topics.items():
        try:
            classes[topic] = msg_class(msgtype)
        except ValueError as exc:
            raise ValueError(f"topic {topic}: {exc}") from None
    stop = {"flag": False}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop["flag"] = True

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    writer = BagWriter(out, overwrite=overwrite, storage=storage)
    log(f"writing into {writer.tmpdir} until stopped (killed: `tire-model info --salvage {out}`)")
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("tire_model_recorder", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    total = {"n": 0}
    seen = {topic: TopicCount() for topic in topics}
    try:
        for topic, msgtype in topics.items():
            writer.add_topic(topic, msgtype)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_ALL, depth=queue, reliability=ReliabilityPolicy.RELIABLE
        )
        for topic in topics:

            def callback(data: bytes, info: Mapping[str, Any], topic: str = topic) -> None:
                c = seen[topic]
                c.seen(info.get("publication_sequence_number"))
                if count is not None and total["n"] >= count:
                    c.ignored += 1
                    return
                writer.write(topic, _stamp_ns(data, time.time_ns()), data)
                c.recorded += 1
                total["n"] += 1

            # rclpy hands a callback of two arguments the message info too (its stubs say one)
            node.create_subscription(classes[topic], topic, callback, qos, raw=True)  # type: ignore[arg-type]
        log(f"recording {len(topics)} topic(s) to {out}")
        end = None if duration_s is None else time.monotonic() + duration_s
        while not stop["flag"] and (count is None or total["n"] < count):
            if end is not None and time.monotonic() >= end:
                break
            executor.spin_once(timeout_sec=0.05)
            # complete chunks on disk at least every mcap_stream.FLUSH_S: a recorder killed
            # with SIGKILL loses only that; `tire-model info --salvage OUT -o BAG` reads the rest
            writer.flush_due()
        writer.close()
        for topic, c in seen.items():
            log(report_line(RECORD, topic, c.counts()))
        missing = {t: c.gaps for t, c in seen.items() if c.gaps}
        if missing:
            log(f"record: messages that never reached the recorder: {missing}")
        log(f"recorded {total['n']} messages to {out}")
        return dict(writer.counts)
    except BaseException:
        # keep what was recorded: a valid, shorter bag beats none; drop it only if unusable
        try:
            writer.close()
        except Exception:
            writer.abort()
        raise
    finally:
        with deadline():  # the bag is closed by now
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=context)
        for s, handler in old.items():
            signal.signal(s, handler)
