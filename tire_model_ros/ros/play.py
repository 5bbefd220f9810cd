"""Play a recording's input topics into ROS 2 with their original timing (rclpy; ROS glue).

The CDR bytes from the bag are published as they are (``publish`` of raw bytes), so header
stamps and values reach subscribers bit for bit. The schedule is pure (``schedule``) and
tested without ROS; ``play`` only sleeps and publishes. No silent loss: play never lets its
reliable queue drop a message a subscriber has not acknowledged (it waits, falling behind its
schedule, and says so), and reports per topic what it published and whether every subscriber
acknowledged it (``play report`` lines, :mod:`tire_model_ros.delivery`).
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tire_model_ros.delivery import PLAY, report_line
from tire_model_ros.recording import RawBag, RecordingError, cdr, read_raw
from tire_model_ros.ros.msg_types import msg_class
from tire_model_ros.ros.teardown import deadline as teardown_deadline
from tire_model_ros.vocabulary import CHANNEL_TYPES, NODE_INPUTS, NS_PER_S

INPUTS = (*NODE_INPUTS, "slip")  # slip last: at equal stamps the inputs come first


@dataclass
class Schedule:
    """Messages to publish, in order: ``topics[topic_idx[i]]`` gets ``raw[...]`` at
    ``stamp_ns[i]``; ``raw_of(i)`` gives the bytes."""

    topics: list[str]
    msgtypes: list[str]
    topic_idx: np.ndarray
    msg_idx: np.ndarray
    stamp_ns: np.ndarray
    bag: RawBag

    def __len__(self) -> int:
        return len(self.stamp_ns)

    def raw_of(self, i: int) -> bytes:
        return self.bag.topics[self.topics[self.topic_idx[i]]].message(int(self.msg_idx[i]))


def _channel_rank(topic: str) -> int:
    channel = topic.rpartition("/")[2]
    return INPUTS.index(channel) if channel in INPUTS else len(INPUTS) - 1  # measured ~ slip-1


def select_topics(
    all_topics: Sequence[str], wheels: Sequence[str] | None, measured: bool
) -> list[str]:
    """Input topics of every wheel (a prefix with ``P/slip``), optionally measured_forces."""
    channels = set(INPUTS) | ({"measured_forces"} if measured else set())
    prefixes = {t.rpartition("/")[0] for t in all_topics if t.endswith("/slip")}
    if wheels is not None:
        if missing := sorted(set(wheels) - prefixes):
            raise RecordingError(f"no wheel {', '.join(missing)} in the bag (no P/slip topic)")
        prefixes = set(wheels)
    return sorted(
        t
        for t in all_topics
        if t.rpartition("/")[0] in prefixes and t.rpartition("/")[2] in channels
    )


def schedule(bag: RawBag) -> Schedule:
    """All messages of ``bag`` ordered by header stamp; at equal stamps load, pressure,
    temperature, velocity, then measured_forces, then slip (the node computes on slip and must
    have seen the others); then bag order."""
    topics = sorted(bag.topics)
    parts = []
    for i, topic in enumerate(topics):
        raw = bag.topics[topic]
        expected = CHANNEL_TYPES.get(topic.rpartition("/")[2])
        if expected and raw.msgtype != expected:
            raise RecordingError(
                f"{bag.path}: topic {topic} has message type {raw.msgtype}, expected {expected}"
            )
        if len(raw) and (np.any(raw.lens < 12) or np.any(raw.buf[raw.starts + 1] != 1)):
            raise RecordingError(f"{bag.path}: topic {topic}: messages are not CDR_LE stamped")
        stamps = cdr.header_stamps(raw.buf, raw.starts)
        order_rank = _channel_rank(topic) * 2 + (1 if topic.endswith("/slip") else 0)
        parts.append(
            (np.full(len(raw), i), np.arange(len(raw)), stamps, np.full(len(raw), order_rank))
        )
    if not parts:
        raise RecordingError(f"{bag.path}: nothing to play")
    t_idx, m_idx, stamp, rank = (np.concatenate(x) for x in zip(*parts, strict=True))
    order = np.lexsort((m_idx, t_idx, rank, stamp))
    return Schedule(
        topics,
        [bag.topics[t].msgtype for t in topics],
        t_idx[order],
        m_idx[order],
        stamp[order],
        bag,
    )


def load_schedule(
    path: str | os.PathLike[str],
    wheels: Sequence[str] | None = None,
    measured: bool = False,
    salvage: bool = False,
) -> Schedule:
    """Read the bag's topics to play and order them (``salvage``: see ``read_raw``)."""
    listing = read_raw(path, lambda _t: False, salvage=salvage)  # topic table only
    chosen = set(select_topics(list(listing.all_topics), wheels, measured))
    if not chosen:
        raise RecordingError(f"{path}: no input topics to play (no P/slip topic)")
    return schedule(read_raw(path, lambda t: t in chosen, salvage=salvage))


#: How long play waits for every subscriber to acknowledge a window of messages [s].
ACK_WAIT_S = 10.0
# Fast DDS (the rmw here) acknowledges a reliable writer's samples when the writer's heartbeat
# asks, every 3 s by default: each of play's waits then took about 3 s (a 594 s session played
# at rate 20 took 275 s, falling 245 s behind). Play's writers beat every 20 ms: a wait takes
# about 15 ms. Profiles only: every QoS stays the one play sets.
FASTDDS_PROFILES_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"  # Fast DDS 2.x, as in ROS 2 Jazzy
HEARTBEAT_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <data_writer profile_name="tire_model_play" is_default_profile="true">
      <times><heartbeatPeriod><sec>0</sec><nanosec>20000000</nanosec></heartbeatPeriod></times>
    </data_writer>
  </profiles>
</dds>
"""


@dataclass
class PlayReport:
    """What play delivered, per topic (:mod:`tire_model_ros.delivery`): messages published,
    whether every reliable subscriber acknowledged them all, subscribers when it started."""

    published: dict[str, int]
    acknowledged: dict[str, bool]
    subscribers: dict[str, int]
    backpressure_waits: int = 0  # windows play waited for before going on
    max_lag_s: float = 0.0  # how far behind its schedule it fell by waiting
    ack_wait_s: float = 0.0  # time spent in those waits

    @property
    def total(self) -> int:
        return sum(self.published.values())

    def lines(self) -> list[str]:
        """One ``play report`` line per topic, then what was not delivered, in words."""
        out = []
        for t, n in self.published.items():
            counts = {"published": n, "acknowledged": int(self.acknowledged[t])}
            out.append(report_line(PLAY, t, counts | {"subscribers": self.subscribers[t]}))
        nobody = [t for t, n in self.subscribers.items() if n == 0 and self.published[t]]
        unacked = [t for t, ok in self.acknowledged.items() if not ok and t not in nobody]
        if nobody:
            out.append(f"play: no subscriber on {', '.join(nobody)}: those messages went to nobody")
        if unacked:
            out.append(f"play: not acknowledged by every subscriber: {', '.join(unacked)} "
                       "(messages may be lost there)")  # fmt: skip
        if self.backpressure_waits:
            out.append(f"play: waited {self.backpressure_waits} times for subscribers to keep "
                       f"up ({self.ack_wait_s:.2f} s in all), at most {self.max_lag_s:.2f} s "
                       "behind the schedule")  # fmt: skip
        return out


def play(
    path: str | os.PathLike[str],
    *,
    rate: float = 1.0,
    loop: bool = False,
    wheels: Sequence[str] | None = None,
    measured: bool = False,
    salvage: bool = False,  # read_raw(salvage=True): what can be trusted, its report logged
    queue: int = 1000,
    wait_subscribers_s: float = 2.0,
    should_stop: Callable[[], bool] = lambda: False,
    log: Callable[[str], None] = print,
) -> PlayReport:
    """Publish the recording; what was published and delivered (:class:`PlayReport`).

    ``rate`` scales the original timing (2 = twice as fast); 0 publishes as fast as possible
    (reliable QoS, history depth ``queue`` on the publisher). Waits up to
    ``wait_subscribers_s`` for a subscriber on every topic before starting. Never overwrites a
    message a subscriber has not acknowledged: after every ``queue // 2`` messages of a topic
    it waits (up to :data:`ACK_WAIT_S`) until they are acknowledged, falling behind the
    schedule when a subscriber cannot keep up, and at the end for all of them.
    """
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    if not rate >= 0 or not np.isfinite(rate):
        raise ValueError(f"--rate must be >= 0, got {rate}")
    sched = load_schedule(path, wheels, measured, salvage)
    if salvage:
        for line in sched.bag.salvage_report():
            log(f"salvage: {line}")
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=queue, reliability=ReliabilityPolicy.RELIABLE
    )
    own_context = not rclpy.ok()
    with writer_heartbeat(own_context, log):
        if own_context:
            # rclpy's own SIGINT/SIGTERM handlers would shut the context down under the last
            # publish and its acknowledgement wait; stopping is ``should_stop``'s (the CLI's)
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("tire_model_player")
    report = PlayReport(dict.fromkeys(sched.topics, 0), dict.fromkeys(sched.topics, True), {})
    try:
        pubs = [
            node.create_publisher(msg_class(mt), t, qos)
            for t, mt in zip(sched.topics, sched.msgtypes, strict=True)
        ]
        _wait_for_subscribers(pubs, wait_subscribers_s, should_stop)
        report.subscribers = {p.topic_name: p.get_subscription_count() for p in pubs}
        log(
            f"playing {len(sched)} messages on {len(pubs)} topics from {path} "
            f"(rate {'max' if rate == 0 else rate})"
        )
        _publish(sched, pubs, rate, loop, max(1, queue // 2), should_stop, report)
        for pub in pubs:
            if not _acked(pub, ACK_WAIT_S / 2):
                report.acknowledged[pub.topic_name] = False
        return report
    finally:
        with teardown_deadline():  # every message acknowledged (or the wait timed out) by now
            node.destroy_node()
            if own_context:
                rclpy.try_shutdown()


@contextmanager
def writer_heartbeat(own_context: bool, log: Callable[[str], None]) -> Iterator[None]:
    """While play's DDS participant is made: Fast DDS' profile for play's writers
    (:data:`HEARTBEAT_PROFILE`), unless the user gives Fast DDS profiles of their own, another
    rmw is chosen or the process' context (and its participant) exists already."""
    rmw = os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    if (
        not own_context
        or rmw != "rmw_fastrtps_cpp"
        or Path("DEFAULT_FASTRTPS_PROFILES.xml").exists()
    ):
        yield
        return
    if os.environ.get(FASTDDS_PROFILES_ENV):
        log(f"play: {FASTDDS_PROFILES_ENV} is set: its writers' heartbeat paces play's "
            "acknowledgement waits (Fast DDS' default: 3 s each)")  # fmt: skip
        yield
        return
    with tempfile.TemporaryDirectory(prefix="tire_model_play_") as d:
        path = Path(d) / "play_writers.xml"
        path.write_text(HEARTBEAT_PROFILE)
        os.environ[FASTDDS_PROFILES_ENV] = str(path)
        try:
            yield
        finally:
            del os.environ[FASTDDS_PROFILES_ENV]


def _wait_for_subscribers(pubs: list[Any], seconds: float, should_stop: Callable[[], bool]) -> None:
    wait_until = time.monotonic() + seconds
    while (
        any(p.get_subscription_count() == 0 for p in pubs)
        and time.monotonic() < wait_until
        and not should_stop()
    ):
        time.sleep(0.01)


def _acked(pub: Any, seconds: float, report: PlayReport | None = None) -> bool:
    from rclpy.duration import Duration

    t0 = time.monotonic()
    ok = bool(pub.wait_for_all_acked(Duration(seconds=seconds)))
    if report is not None:
        report.ack_wait_s += time.monotonic() - t0
    return ok


def _publish(
    sched: Schedule,
    pubs: list[Any],
    rate: float,
    loop: bool,
    window: int,
    should_stop: Callable[[], bool],
    report: PlayReport,
) -> None:
    """The schedule's messages at their time; every ``window`` messages of a topic, wait until
    they are acknowledged (KEEP_LAST would drop an unacknowledged one to make room)."""
    raw = [sched.raw_of(i) for i in range(len(sched))]
    rel_s = (sched.stamp_ns - sched.stamp_ns[0]) / NS_PER_S
    t_idx = sched.topic_idx.tolist()
    since_ack = [0] * len(pubs)
    while True:
        start = time.monotonic()
        for i in range(len(raw)):
            if should_stop():
                return
            due = start + rel_s[i] / rate if rate > 0 else time.monotonic()
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            k = t_idx[i]
            pubs[k].publish(raw[i])
            report.published[pubs[k].topic_name] += 1
            since_ack[k] += 1
            if since_ack[k] >= window:
                since_ack[k] = 0
                report.backpressure_waits += 1
                if not _acked(pubs[k], ACK_WAIT_S, report):
                    report.acknowledged[pubs[k].topic_name] = False
                report.max_lag_s = max(report.max_lag_s, time.monotonic() - due)
        if not loop:
            return
