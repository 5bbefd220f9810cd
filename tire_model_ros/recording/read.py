"""Reading recordings (rosbag2 bags): raw messages, topic decoding, aligned ``WheelSeries``.

Formats read: a rosbag2 folder (metadata.yaml + .mcap or .db3, CDR), a lone ``.mcap`` or
``.db3`` file. A wheel is a prefix P with ``P/slip``, ``P/load`` and ``P/measured_forces``;
other topics are ignored. Receive (log) times order messages of equal stamp (log time, then
file order) and are used for nothing else; the samples follow the alignment rule of
:mod:`.align`.

MCAP files are read by this package (``mcap_scan.read_mcap``): through their chunk and
message indexes with numpy (``mcap_index``), else record by record; every CRC the file carries
is checked. CDR is decoded with fixed layouts (``cdr``; rosbags' deserialiser is the reference
and the fallback for odd messages). sqlite3 bags go through rosbags; when its metadata.yaml
route yields fewer messages than metadata ``message_count`` (QoS in metadata.yaml differing
from the storage file's makes it yield none), the storage files are opened directly
(``RawBag.fallback``). A metadata.yaml that lists a file twice, or whose counts disagree with
what the files hold, is refused (``metadata``).

Errors are ``RecordingError`` (a ``ValueError``) naming the file and, where one is concerned,
the topic; rosbags' own exceptions never reach the caller. A damaged bag is refused with a
``DamagedBagError`` naming the file, the byte offset and the topics, or read with
``salvage=True``, which skips what is damaged and lists it (``RawBag.salvage_report``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_model_ros.recording import cdr
from tire_model_ros.recording.align import align_wheel
from tire_model_ros.recording.errors import Damage, DamagedBagError, RecordingError
from tire_model_ros.recording.mcap_scan import read_mcap
from tire_model_ros.recording.metadata import BagMetadata
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import CHANNEL_TYPES, OPTIONAL_CHANNELS, REQUIRED_CHANNELS

if TYPE_CHECKING:
    from rosbags.interfaces import Connection
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

#: Which topics to keep: topic name -> keep it.
Select = Callable[[str], bool]
#: Every topic of a bag -> (message type, message count).
TopicTable = dict[str, tuple[str, int]]


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
class _Part:
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


class _Collector:
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


def _msgdefs(connections: Iterable[Connection]) -> dict[str, str]:
    return {c.msgtype: c.msgdef.data for c in connections}


def _read_storage_file(path: Path, select: Select, salvage: bool) -> _Part:
    """One .mcap (this package's reader, CRCs checked) or .db3 (rosbags) storage file."""
    if path.suffix != ".db3":
        got = read_mcap(path, select, salvage)
        topics = {
            t: RawTopic(mt, got.buffer, starts, lens, log)
            for t, (mt, starts, lens, log) in got.topics.items()
        }
        found = sum(n for _, n in got.table.values())
        return _Part(path, topics, found, got.announced, got.table, got.damages, got.msgdefs)
    try:
        reader = _open_sqlite3(path)
        try:
            collector = _Collector(select)
            collector.add(reader.messages(reader.connections))
            announced = reader.metadata.message_count
            table = collector.table(reader.connections)
            msgdefs = _msgdefs(reader.connections)
        finally:
            reader.close()
    except Exception as exc:
        if not salvage:
            raise
        reason = f"unreadable ({type(exc).__name__}: {exc}): skipped"
        return _Part(path, {}, 0, 0, {}, [Damage(path, "file", reason)], {})
    return _Part(path, collector.topics(), collector.count, announced, table, [], msgdefs)


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


def _bag(
    path: Path, storage: str, parts: list[_Part], announced: int | None, fallback: bool = False
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


def _one_line(lines: list[str]) -> str:
    return lines[0] + (f" (and {len(lines) - 1} more)" if len(lines) > 1 else "")


def _read_with_rosbags(path: Path, select: Select) -> tuple[RawBag, list[_Part]]:
    """A folder through rosbags' Reader (sqlite3, rosbag2-compressed, metadata this package
    does not parse); uncompressed MCAP files then through this package's reader."""
    from rosbags.rosbag2 import Reader

    with Reader(path) as reader:  # validates metadata.yaml (version, files, plugin)
        # One storage reader per file of a split bag (an attribute of rosbags' concrete class).
        storages: list[Any] = reader.storage.storages  # type: ignore[attr-defined]
        plugin = type(storages[0]).__name__ if storages else ""
        storage = "sqlite3" if "Sqlite" in plugin else "mcap"
        connections = list(reader.connections)
        announced = reader.message_count
        compressed = reader.compression_mode
        files = [Path(s.path) for s in storages]
        collector: _Collector | None = None
        if storage != "mcap" or compressed:
            collector = _Collector(select)
            collector.add(reader.messages())
    if collector is not None and (collector.count >= announced or compressed):
        bag = RawBag(
            path,
            storage,
            collector.topics(),
            collector.table(connections),
            announced,
            collector.count,
            msgdefs=_msgdefs(connections),
        )
        return bag, []
    # Uncompressed MCAP: read the files through their own index (fast). Also the fallback when
    # rosbags' metadata.yaml route yields too few messages: it matches the metadata's topics to
    # the storage file's including QoS, and yields nothing for a topic whose QoS differ.
    parts = [_read_storage_file(f, select, salvage=False) for f in files]
    return _bag(path, storage, parts, announced, fallback=collector is not None), parts


def _read_dir(path: Path, select: Select, salvage: bool) -> RawBag:
    meta = BagMetadata.load(path)
    if salvage:
        return _salvage_dir(path, select, meta)
    if meta is not None and (duplicates := meta.duplicates()):
        raise RecordingError(f"{meta.path}: {_one_line(duplicates)}")
    if meta is not None and meta.simple_mcap():
        parts = [_read_storage_file(f, select, False) for f in meta.storage_files()]
        bag = _bag(path, "mcap", parts, meta.message_count)
    else:
        bag, parts = _read_with_rosbags(path, select)
    if meta is not None:
        per_file = {p.file.name: p.found for p in parts} if parts else None
        topics = {t: n for t, (_, n) in bag.all_topics.items()}
        if disagree := meta.disagreements(bag.messages_read, topics, per_file):
            raise RecordingError(f"{meta.path}: {_one_line(disagree)}")
    return bag


def _storage_files_in(folder: Path) -> list[Path]:
    """Storage files of a folder without metadata.yaml: its own, else its subfolders' (the
    temporary folder of a recorder holds the bag folder)."""
    for pattern in ("", "*/"):
        files = sorted(folder.glob(f"{pattern}*.mcap")) + sorted(folder.glob(f"{pattern}*.db3"))
        if files:
            return files
    return []


def _salvage_dir(path: Path, select: Select, meta: BagMetadata | None) -> RawBag:
    """Every readable storage file of a folder, each once; what disagrees is noted."""
    notes: list[Damage] = []
    if meta is not None:
        notes += [Damage(meta.path, "metadata", f"{line}: read once") for line in meta.duplicates()]
        files = meta.storage_files()
        missing = [f for f in files if not f.is_file()]
        notes += [Damage(f, "file", "listed in metadata.yaml, missing") for f in missing]
        files = [f for f in files if f.is_file()]
    else:
        files = _storage_files_in(path)
        what = f"no metadata.yaml: read {len(files)} storage file(s)"
        notes.append(Damage(path, "metadata", what))
    if not files:
        raise RecordingError(f"{path}: no storage file (.mcap, .db3) to salvage")
    parts = [_read_storage_file(f, select, salvage=True) for f in files]
    storage = "sqlite3" if all(f.suffix == ".db3" for f in files) else "mcap"
    bag = _bag(path, storage, parts, meta.message_count if meta else None)
    if meta is not None:
        topics = {t: n for t, (_, n) in bag.all_topics.items()}
        per_file = {p.file.name: p.found for p in parts}
        notes += [
            Damage(meta.path, "metadata", f"{line} (the files' counts are used)")
            for line in meta.disagreements(bag.messages_read, topics, per_file)
        ]
    bag.damages = notes + bag.damages
    bag.salvaged = True
    return bag


def _read_file(path: Path, select: Select, salvage: bool) -> RawBag:
    part = _read_storage_file(path, select, salvage)
    bag = _bag(path, storage_of(path), [part], part.announced)
    bag.salvaged = salvage
    return bag


def _leftovers(path: Path) -> list[Path]:
    """Temporary folders that an interrupted writer of ``path`` left beside it."""
    return sorted(p for p in path.parent.glob(f".{path.name}.*.tmp") if p.is_dir())


def _missing(path: Path, salvage: bool) -> Path:
    """What to read for a path that does not exist: with ``salvage``, the one temporary folder
    an interrupted recorder left for it; else an error (naming such folders)."""
    left = _leftovers(path)
    if salvage and len(left) == 1:
        return left[0]
    if not left:
        raise RecordingError(f"{path}: no such file or directory")
    hint = "--salvage reads it" if len(left) == 1 else "salvage one of them"
    raise RecordingError(
        f"{path}: no such file or directory; an interrupted recording left "
        f"{', '.join(str(p) for p in left)} ({hint})"
    )


def read_raw(
    path: str | os.PathLike[str], select: Select | None = None, *, salvage: bool = False
) -> RawBag:
    """Undecoded messages of the topics for which ``select(topic)`` is true (all if None).

    Parameters
    ----------
    salvage : read what can be trusted of a damaged or unclosed bag instead of refusing it:
        skip damaged chunks, read an MCAP file without its footer up to its last complete
        chunk, a folder without metadata.yaml (a recorder's temporary folder too; a missing
        ``path`` whose recorder left one), each listed file once. ``RawBag.damages`` and
        ``salvage_report()`` say what was skipped and what was recovered.

    Raises
    ------
    RecordingError
        Missing path, not a bag, truncated or corrupted container (message names the file);
        ``DamagedBagError`` for a CRC mismatch or an unclosed file (file, byte offset, topics).
    """
    path = Path(path)
    select = select or (lambda _topic: True)
    note: list[Damage] = []
    if not path.exists():
        found = _missing(path, salvage)
        note.append(Damage(path, "file", f"does not exist; read {found}, left by its recorder"))
        path = found
    if path.is_dir():
        if not (path / "metadata.yaml").is_file() and not salvage:
            files = _storage_files_in(path)
            hint = f"; it holds {len(files)} storage file(s): --salvage reads them" if files else ""
            raise RecordingError(f"{path}: not a rosbag2 folder (no metadata.yaml){hint}")
        reader = _read_dir
    elif path.suffix in (".mcap", ".db3"):
        reader = _read_file
    else:
        raise RecordingError(f"{path}: not a bag (expected a rosbag2 folder, .mcap or .db3 file)")
    try:
        bag = reader(path, select, salvage)
    except DamagedBagError:
        raise
    except RecordingError as exc:
        said = str(exc)  # named by its bag's path once
        raise RecordingError(said if said.startswith(str(path)) else f"{path}: {said}") from None
    except Exception as exc:  # rosbags/apsw/struct raise many types on damaged files
        raise RecordingError(
            f"{path}: cannot read the bag, truncated or corrupted? ({type(exc).__name__}: {exc})"
        ) from None
    bag.damages = note + bag.damages
    return bag


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
        "damages": [d.describe() for d in bag.damages],
    }
    return series


def wheel_select(wheels: Sequence[str] | None = None) -> Select:
    """The topics ``read_recording`` reads: the wheel channels of ``wheels`` (None: every
    prefix)."""
    wanted = set(wheels) if wheels is not None else None

    def select(topic: str) -> bool:
        prefix, _, channel = topic.rpartition("/")
        wheel_channel = channel in REQUIRED_CHANNELS or channel in OPTIONAL_CHANNELS
        return wheel_channel and (wanted is None or prefix in wanted)

    return select


def read_recording(
    path: str | os.PathLike[str], *, wheels: Sequence[str] | None = None, salvage: bool = False
) -> dict[str, WheelSeries]:
    """Every wheel of a recording as aligned samples (module docstring: the rules).

    Parameters
    ----------
    path : rosbag2 folder, ``.mcap`` or ``.db3`` file.
    wheels : prefixes to read (default: every complete wheel). A prefix asked for that is not a
        complete wheel is an error.
    salvage : read a damaged or unclosed bag as ``read_raw`` does; each wheel's
        ``meta["damages"]`` lists what was skipped.

    Raises
    ------
    RecordingError
        Unreadable bag, no complete wheel (names what is missing), wrong type on a known topic;
        ``DamagedBagError`` for a damaged bag read without ``salvage``.
    """
    return wheels_from_raw(read_raw(path, wheel_select(wheels), salvage=salvage), wheels)


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
