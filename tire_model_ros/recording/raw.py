"""Raw access to storage files: each .mcap (this package's reader, every CRC checked) or .db3
(rosbags) file as undecoded messages per topic (``RawTopic``), the files of a bag joined into
one ``RawBag``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tire_model_ros.recording import cdr
from tire_model_ros.recording.errors import Damage, RecordingError
from tire_model_ros.recording.mcap_scan import read_mcap

if TYPE_CHECKING:
    from rosbags.interfaces import Connection
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

#: Which topics to keep: topic name -> keep it.
Select = Callable[[str], bool]
#: Every topic of a bag -> (message type, message count).
TopicTable = dict[str, tuple[str, int]]


@dataclass
class RawTopic:
    """The undecoded messages of one topic, in bag order (log time; ties: file order).

    Message i is ``buf[starts[i] : starts[i] + lens[i]]`` (CDR bytes).
    """

    msgtype: str
    buf: np.ndarray
    starts: np.ndarray
    lens: np.ndarray
    log_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.starts)

    def message(self, i: int) -> bytes:
        return self.buf[self.starts[i] : self.starts[i] + self.lens[i]].tobytes()


@dataclass
class RawBag:
    """Messages of the selected topics, plus what the container says about all topics.

    ``damages``: what a salvaging read skipped or found disagreeing (empty otherwise: a damaged
    bag is refused); ``msgdefs``: message type -> definition text, where the files carry it.
    """

    path: Path
    storage: str  # "mcap" or "sqlite3"
    topics: dict[str, RawTopic]  # selected topics only
    all_topics: dict[str, tuple[str, int]]  # every topic -> (type, messages found)
    message_count: int  # messages the container announces (metadata / summary)
    messages_read: int  # messages actually found (all topics)
    fallback: bool = False  # True: the metadata.yaml route found too few; read the file itself
    damages: list[Damage] = field(default_factory=list)
    salvaged: bool = False  # read with salvage=True
    msgdefs: dict[str, str] = field(default_factory=dict)

    def salvage_report(self) -> list[str]:
        """What a salvaging read skipped (one line each) and what it recovered per topic."""
        lines = [
            f"skipped {d.describe()}; {d.lost_text()}" if d.what == "chunk" else d.describe()
            for d in self.damages
        ]
        if not self.damages:
            lines.append(f"{self.path}: no damage found")
        recovered = ", ".join(f"{t} {n}" for t, (_, n) in sorted(self.all_topics.items()))
        lines.append(f"recovered {self.messages_read} messages: {recovered or 'none'}")
        return lines


@dataclass
class Part:
    """What one storage file gave."""

    file: Path
    topics: dict[str, RawTopic]
    found: int  # messages found (all topics)
    announced: int
    table: TopicTable
    damages: list[Damage]
    msgdefs: dict[str, str]


def storage_of(path: Path) -> str:
    """The storage a lone file's suffix names: "sqlite3" for .db3, else "mcap"."""
    return "sqlite3" if path.suffix == ".db3" else "mcap"


def _open_sqlite3(path: Path) -> Sqlite3Reader:
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    reader = Sqlite3Reader(path)
    reader.open()
    return reader


class Collector:
    """Gathers (topic, log time, bytes) from rosbags' iterators into ``RawTopic`` arrays."""

    def __init__(self, select: Select) -> None:
        self.select = select
        self.count = 0
        self.per_topic: dict[str, int] = {}
        self.parts: dict[str, tuple[str, list[bytes], list[int]]] = {}

    def add(self, messages: Iterable[tuple[Connection, int, bytes]]) -> None:
        for conn, log_ns, data in messages:
            self.count += 1
            self.per_topic[conn.topic] = self.per_topic.get(conn.topic, 0) + 1
            if self.select(conn.topic):
                part = self.parts.get(conn.topic)
                if part is None:
                    part = self.parts[conn.topic] = (conn.msgtype, [], [])
                elif part[0] != conn.msgtype:
                    raise RecordingError(
                        f"topic {conn.topic} has two message types: {part[0]} and {conn.msgtype}"
                    )
                part[1].append(data)
                part[2].append(log_ns)

    def topics(self) -> dict[str, RawTopic]:
        out: dict[str, RawTopic] = {}
        for topic, (msgtype, data, log_ns) in self.parts.items():
            buf, starts, lens = cdr.join(data)
            log = np.asarray(log_ns, np.int64)
            order = np.argsort(log, kind="stable")
            out[topic] = RawTopic(msgtype, buf, starts[order], lens[order], log[order])
        return out

    def table(self, connections: Iterable[Connection]) -> TopicTable:
        """Every topic of ``connections`` with the messages found of it."""
        return {c.topic: (c.msgtype, self.per_topic.get(c.topic, 0)) for c in connections}


def msgdefs_of(connections: Iterable[Connection]) -> dict[str, str]:
    return {c.msgtype: c.msgdef.data for c in connections}


def read_storage_file(path: Path, select: Select, salvage: bool) -> Part:
    """One .mcap (this package's reader, CRCs checked) or .db3 (rosbags) storage file."""
    if path.suffix != ".db3":
        got = read_mcap(path, select, salvage)
        topics = {
            t: RawTopic(mt, got.buffer, starts, lens, log)
            for t, (mt, starts, lens, log) in got.topics.items()
        }
        found = sum(n for _, n in got.table.values())
        return Part(path, topics, found, got.announced, got.table, got.damages, got.msgdefs)
    try:
        reader = _open_sqlite3(path)
        try:
            collector = Collector(select)
            collector.add(reader.messages(reader.connections))
            announced = reader.metadata.message_count
            table = collector.table(reader.connections)
            msgdefs = msgdefs_of(reader.connections)
        finally:
            reader.close()
    except Exception as exc:
        if not salvage:
            raise
        reason = f"unreadable ({type(exc).__name__}: {exc}): skipped"
        return Part(path, {}, 0, 0, {}, [Damage(path, "file", reason)], {})
    return Part(path, collector.topics(), collector.count, announced, table, [], msgdefs)


def _compact(t: RawTopic) -> tuple[np.ndarray, np.ndarray]:
    """The topic's message bytes back to back, and each message's start in them."""
    new_starts = np.zeros(len(t), np.int64)
    if len(t):
        np.cumsum(t.lens[:-1], out=new_starts[1:])
    pos = np.repeat(t.starts - new_starts, t.lens) + np.arange(int(t.lens.sum()), dtype=np.int64)
    return t.buf[pos], new_starts


def _merge(parts: list[dict[str, RawTopic]]) -> dict[str, RawTopic]:
    """Topics of several storage files (a split bag) as one, in log-time order."""
    out: dict[str, RawTopic] = {}
    for topic in dict.fromkeys(t for part in parts for t in part):
        pieces = [part[topic] for part in parts if topic in part]
        if len(pieces) == 1:
            out[topic] = pieces[0]
            continue
        if len({p.msgtype for p in pieces}) > 1:
            raise RecordingError(f"topic {topic} has different message types in different files")
        bufs, starts, base = [], [], 0
        for p in pieces:
            buf, st = _compact(p)
            bufs.append(buf)
            starts.append(st + base)
            base += len(buf)
        start = np.concatenate(starts)
        lens = np.concatenate([p.lens for p in pieces])
        log = np.concatenate([p.log_ns for p in pieces])
        order = np.argsort(log, kind="stable")
        out[topic] = RawTopic(
            pieces[0].msgtype, np.concatenate(bufs), start[order], lens[order], log[order]
        )
    return out


def bag_of(
    path: Path, storage: str, parts: list[Part], announced: int | None, fallback: bool = False
) -> RawBag:
    """One RawBag of the storage files' parts; ``announced`` None: what the files announce."""
    table: TopicTable = {}
    for part in parts:
        for t, (mt, c) in part.table.items():
            table[t] = (mt, table.get(t, (mt, 0))[1] + c)
    return RawBag(
        path,
        storage,
        _merge([p.topics for p in parts]),
        table,
        sum(p.announced for p in parts) if announced is None else announced,
        sum(p.found for p in parts),
        fallback,
        damages=[d for p in parts for d in p.damages],
        msgdefs={k: v for p in parts for k, v in p.msgdefs.items()},
    )


def read_file(path: Path, select: Select, salvage: bool) -> RawBag:
    part = read_storage_file(path, select, salvage)
    bag = bag_of(path, storage_of(path), [part], part.announced)
    bag.salvaged = salvage
    return bag
