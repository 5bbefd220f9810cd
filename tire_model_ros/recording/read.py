"""Reading recordings (rosbag2 bags): raw messages, topic decoding, aligned ``WheelSeries``.

Formats read: a rosbag2 folder (metadata.yaml + .mcap or .db3, CDR), a lone ``.mcap`` or
``.db3`` file. A wheel is a prefix P with ``P/slip``, ``P/load`` and ``P/measured_forces``;
other topics are ignored. Receive (log) times order messages of equal stamp (log time, then
file order) and are used for nothing else; the samples follow the alignment rule of
:mod:`.align`.

MCAP files are read through their chunk and message indexes with numpy (``mcap_index``), CDR
decoded with fixed layouts (``cdr``; rosbags' deserialiser is the reference and the fallback
for odd messages). sqlite3 bags and unindexed MCAP go through rosbags; when its metadata.yaml
route yields fewer messages than metadata ``message_count`` (QoS in metadata.yaml differing
from the storage file's makes it yield none), the storage files are opened directly
(``RawBag.fallback``).

Errors are ``RecordingError`` (a ``ValueError``) naming the file and, where one is concerned,
the topic; rosbags' own exceptions never reach the caller.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_model_ros.recording import cdr, mcap_index
from tire_model_ros.recording.align import align_wheel
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import CHANNEL_TYPES, OPTIONAL_CHANNELS, REQUIRED_CHANNELS

if TYPE_CHECKING:
    from rosbags.interfaces import Connection
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

#: Which topics to keep: topic name -> keep it.
Select = Callable[[str], bool]
#: Every topic of a bag -> (message type, message count).
TopicTable = dict[str, tuple[str, int]]


class RecordingError(ValueError):
    """A recording that cannot be read or written; the message names the file and topic."""


# --------------------------------------------------------------------------- raw access


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
    """Messages of the selected topics, plus what the container says about all topics."""

    path: Path
    storage: str  # "mcap" or "sqlite3"
    topics: dict[str, RawTopic]  # selected topics only
    all_topics: dict[str, tuple[str, int]]  # every topic -> (type, count in metadata/index)
    message_count: int  # messages the container announces (metadata / summary)
    messages_read: int  # messages actually found (all topics)
    fallback: bool = False  # True: the metadata.yaml route found too few; read the file itself


def storage_of(path: Path) -> str:
    """The storage a lone file's suffix names: "sqlite3" for .db3, else "mcap"."""
    return "sqlite3" if path.suffix == ".db3" else "mcap"


def _open_storage_file(path: Path) -> McapReader | Sqlite3Reader:
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    reader = (Sqlite3Reader if path.suffix == ".db3" else McapReader)(path)
    reader.open()
    return reader


class _Collector:
    """Gathers (topic, log time, bytes) from rosbags' iterators into ``RawTopic`` arrays."""

    def __init__(self, select: Select) -> None:
        self.select = select
        self.count = 0
        self.parts: dict[str, tuple[str, list[bytes], list[int]]] = {}

    def add(self, messages: Iterable[tuple[Connection, int, bytes]]) -> None:
        for conn, log_ns, data in messages:
            self.count += 1
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


def _topic_table(connections: Iterable[Connection]) -> TopicTable:
    table: TopicTable = {}
    for c in connections:
        old = table.get(c.topic, (c.msgtype, 0))
        table[c.topic] = (c.msgtype, old[1] + c.msgcount)
    return table


def _read_storage_file(
    path: Path, select: Select
) -> tuple[dict[str, RawTopic], int, int, TopicTable]:
    """(topics, messages found, messages announced, topic table) of one .mcap/.db3 file."""
    if path.suffix == ".mcap":
        fast = mcap_index.read_indexed(path, select)
        if fast is not None:
            table, count, buffer, found = fast
            topics = {
                t: RawTopic(mt, buffer, starts, lens, log)
                for t, (mt, starts, lens, log) in found.items()
            }
            return topics, count, count, table
    reader = _open_storage_file(path)
    try:
        collector = _Collector(select)
        collector.add(reader.messages(reader.connections))
        announced = reader.metadata.message_count
        table = _topic_table(reader.connections)
    finally:
        reader.close()
    return collector.topics(), collector.count, announced, table


def _mcap_files(path: Path) -> tuple[list[Path], int] | None:
    """Storage files and message count of an uncompressed MCAP rosbag2 folder, read from its
    metadata.yaml with PyYAML's C loader; None for anything else (rosbags then reads it)."""
    import yaml

    try:
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        info = yaml.load((path / "metadata.yaml").read_text(), Loader=loader)
        info = info["rosbag2_bagfile_information"]
        files = [path / Path(f).name for f in info["relative_file_paths"]]
        if (
            int(info.get("version", 1)) > 9
            or info["storage_identifier"] != "mcap"
            or str(info.get("compression_mode") or "none").lower() != "none"
            or not files
            or not all(f.is_file() and f.suffix == ".mcap" for f in files)
        ):
            return None
        return files, int(info["message_count"])
    except Exception:  # any surprise: let rosbags read it and report
        return None


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


def _read_files(
    files: Sequence[Path], select: Select
) -> tuple[dict[str, RawTopic], int, TopicTable]:
    parts: list[dict[str, RawTopic]] = []
    count = 0
    table: TopicTable = {}
    for file in files:
        found, n, _, file_table = _read_storage_file(file, select)
        parts.append(found)
        count += n
        for t, (mt, c) in file_table.items():
            table[t] = (mt, table.get(t, (mt, 0))[1] + c)
    return _merge(parts), count, table


def _read_dir(path: Path, select: Select) -> RawBag:
    from rosbags.rosbag2 import Reader

    simple = _mcap_files(path)
    if simple is not None:
        topics, count, table = _read_files(simple[0], select)
        return RawBag(path, "mcap", topics, table, simple[1], count)

    with Reader(path) as reader:  # validates metadata.yaml (version, files, plugin)
        # One storage reader per file of a split bag (an attribute of rosbags' concrete class).
        storages: list[Any] = reader.storage.storages  # type: ignore[attr-defined]
        plugin = type(storages[0]).__name__ if storages else ""
        storage = "sqlite3" if "Sqlite" in plugin else "mcap"
        all_topics = _topic_table(reader.connections)
        announced = reader.message_count
        compressed = reader.compression_mode
        files = [Path(s.path) for s in storages]
        collector: _Collector | None = None
        if storage != "mcap" or compressed:
            collector = _Collector(select)
            collector.add(reader.messages())
    if collector is not None and (collector.count >= announced or compressed):
        return RawBag(path, storage, collector.topics(), all_topics, announced, collector.count)
    # Uncompressed MCAP: read the files through their own index (fast). Also the fallback when
    # rosbags' metadata.yaml route yields too few messages: it matches the metadata's topics to
    # the storage file's including QoS, and yields nothing for a topic whose QoS differ.
    topics, count, _ = _read_files(files, select)
    return RawBag(path, storage, topics, all_topics, announced, count, collector is not None)


def _read_file(path: Path, select: Select) -> RawBag:
    topics, count, announced, table = _read_storage_file(path, select)
    return RawBag(path, storage_of(path), topics, table, announced, count)


def read_raw(path: str | os.PathLike[str], select: Select | None = None) -> RawBag:
    """Undecoded messages of the topics for which ``select(topic)`` is true (all if None).

    Raises
    ------
    RecordingError
        Missing path, not a bag, truncated or corrupted container (message names the file).
    """
    path = Path(path)
    select = select or (lambda _topic: True)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or directory")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise RecordingError(f"{path}: not a rosbag2 folder (no metadata.yaml)")
        reader = _read_dir
    elif path.suffix in (".mcap", ".db3"):
        reader = _read_file
    else:
        raise RecordingError(f"{path}: not a bag (expected a rosbag2 folder, .mcap or .db3 file)")
    try:
        return reader(path, select)
    except RecordingError as exc:
        raise RecordingError(f"{path}: {exc}") from None
    except Exception as exc:  # rosbags/apsw/struct raise many types on damaged files
        raise RecordingError(
            f"{path}: cannot read the bag, truncated or corrupted? ({type(exc).__name__}: {exc})"
        ) from None


# --------------------------------------------------------------------------- decoding


@dataclass
class Channel:
    """Decoded messages of one topic, sorted by header stamp (stable)."""

    topic: str
    stamp_ns: np.ndarray  # int64, sorted
    values: np.ndarray  # (n, k) float64, LAYOUTS order
    log_ns: np.ndarray  # int64


def decode_topic(bag: RawBag, topic: str, expected: str | None = None) -> Channel:
    """Decode one topic; check its type against ``expected`` (default: by channel name)."""
    raw = bag.topics[topic]
    expected = expected or CHANNEL_TYPES.get(topic.rsplit("/", 1)[-1])
    if expected and raw.msgtype != expected:
        raise RecordingError(
            f"{bag.path}: topic {topic} has message type {raw.msgtype}, expected {expected}"
        )
    if raw.msgtype not in cdr.LAYOUTS:
        raise RecordingError(f"{bag.path}: topic {topic}: cannot decode type {raw.msgtype}")
    try:
        stamp, values = cdr.decode(raw.msgtype, raw.buf, raw.starts, raw.lens)
    except cdr.CdrError as exc:
        raise RecordingError(f"{bag.path}: topic {topic}: corrupted {exc}") from None
    order = np.argsort(stamp, kind="stable")
    return Channel(topic, stamp[order], values[order], raw.log_ns[order])


def find_wheels(topics: Iterable[str]) -> tuple[list[str], dict[str, list[str]]]:
    """Complete wheel prefixes, and incomplete ones with their missing required channels."""
    names = set(topics)
    prefixes = {
        prefix
        for prefix, slash, channel in (t.rpartition("/") for t in names)
        if slash and channel in REQUIRED_CHANNELS
    }
    complete: list[str] = []
    partial: dict[str, list[str]] = {}
    for p in sorted(prefixes):
        missing = [c for c in REQUIRED_CHANNELS if f"{p}/{c}" not in names]
        if missing:
            partial[p] = missing
        else:
            complete.append(p)
    return complete, partial


def _align(bag: RawBag, prefix: str) -> WheelSeries:
    """One wheel of ``bag`` decoded and aligned; the reader's figures added to its meta."""
    channels = {
        c: decode_topic(bag, f"{prefix}/{c}")
        for c in (*REQUIRED_CHANNELS, *OPTIONAL_CHANNELS)
        if f"{prefix}/{c}" in bag.topics
    }
    try:
        series = align_wheel(prefix, {c: (ch.stamp_ns, ch.values) for c, ch in channels.items()})
    except ValueError as exc:
        raise RecordingError(f"{bag.path}: {exc}") from None
    series.meta = {
        "source": str(bag.path),
        "storage": bag.storage,
        **series.meta,
        "reader_fallback": bag.fallback,
        "messages_read": bag.messages_read,
        "messages_announced": bag.message_count,
    }
    return series


def read_recording(
    path: str | os.PathLike[str], *, wheels: Sequence[str] | None = None
) -> dict[str, WheelSeries]:
    """Every wheel of a recording as aligned samples (module docstring: the rules).

    Parameters
    ----------
    path : rosbag2 folder, ``.mcap`` or ``.db3`` file.
    wheels : prefixes to read (default: every complete wheel). A prefix asked for that is not a
        complete wheel is an error.

    Raises
    ------
    RecordingError
        Unreadable bag, no complete wheel (names what is missing), wrong type on a known topic.
    """
    path = Path(path)
    wanted = set(wheels) if wheels is not None else None

    def select(topic: str) -> bool:
        prefix, _, channel = topic.rpartition("/")
        wheel_channel = channel in REQUIRED_CHANNELS or channel in OPTIONAL_CHANNELS
        return wheel_channel and (wanted is None or prefix in wanted)

    return wheels_from_raw(read_raw(path, select), wheels)


def wheels_from_raw(bag: RawBag, wheels: Sequence[str] | None = None) -> dict[str, WheelSeries]:
    """``read_recording`` on an already read ``RawBag`` (which must hold the wheel topics)."""
    path = bag.path
    wanted = set(wheels) if wheels is not None else None
    complete, partial = find_wheels(bag.all_topics)
    if wanted is not None:
        for p in sorted(wanted - set(complete)):
            missing = partial.get(p, list(REQUIRED_CHANNELS))
            raise RecordingError(
                f"{path}: wheel {p}: missing topic(s) {', '.join(f'{p}/{c}' for c in missing)}"
            )
        complete = [p for p in complete if p in wanted]
    if not complete:
        detail = "; ".join(
            f"wheel {p} lacks {', '.join(f'{p}/{c}' for c in m)}" for p, m in partial.items()
        )
        raise RecordingError(
            f"{path}: no wheel found (a wheel needs P/slip, P/load and P/measured_forces)"
            + (f": {detail}" if detail else "")
        )
    return {p: _align(bag, p) for p in complete}
