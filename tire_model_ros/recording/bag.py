"""Recordings (rosbag2 bags) as first-class data: read into aligned ``WheelSeries``, write back.

Formats read: a rosbag2 folder (metadata.yaml + .mcap or .db3, CDR), a lone ``.mcap`` or
``.db3`` file. Written: rosbag2 version 9 folders (MCAP by default, sqlite3 on request), or a
lone ``.mcap`` / ``.db3`` file when the target path has that suffix.

Alignment rules (INTERFACE.md "Recordings", with the decisions this module takes):

- A wheel is a prefix P with ``P/slip``, ``P/load`` and ``P/measured_forces``; other topics
  are ignored. Samples are the ``slip`` messages sorted by header.stamp (equal stamps keep
  log-time order); receive (log) times are used for nothing else.
- ``load``, ``pressure``, ``temperature``, ``velocity``: latest message with header.stamp at or
  before the slip stamp (of several with the same stamp, the one logged last: log time, then
  file order).
- ``load`` missing before the first slip: those leading samples are dropped
  (``meta["dropped_no_load"]`` counts them).
- An optional channel that starts after the first slip: the leading samples take its FIRST
  value (a zero-order hold backwards; ``meta["backfilled"][channel]`` counts them). Pressure,
  temperature and speed move slowly and are often logged at a low rate (1-10 Hz); dropping
  samples until the slowest channel's first message would throw away good force data.
- An optional channel without messages (or without a topic) is ``None``.
- ``measured_forces``: the message with the same stamp, else the nearest one (ties: the
  earlier). ``meta["forces_exact"]`` counts exact matches, ``meta["forces_max_dt_s"]`` is the
  largest stamp distance used.
- ``meta["t_ns"]``: the exact integer slip stamps [ns]; ``write_recording`` uses them when they
  still match ``t`` so a read/write round trip keeps stamps to the nanosecond.

Reading: MCAP files are read through their chunk and message indexes with numpy
(``mcap_index``), CDR decoded with fixed layouts (``cdr``; rosbags' deserialiser is the
reference and the fallback for odd messages). sqlite3 bags and unindexed MCAP go through
rosbags; when its metadata.yaml route yields fewer messages than metadata ``message_count``
(QoS in metadata.yaml differing from the storage file's makes it yield none), the storage
files are opened directly (``RawBag.fallback``).

Writing: MCAP with the vectorised writer of ``mcap_write`` (+ metadata.yaml version 9),
sqlite3 and streaming (``BagWriter``) through rosbags' Writer; always into a temp folder beside
the target, then renamed.

Errors are ``RecordingError`` (a ``ValueError``) naming the file and, where one is concerned,
the topic; rosbags' own exceptions never reach the caller.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tire_model_ros.atomic import replace_path
from tire_model_ros.recording import cdr, mcap_index
from tire_model_ros.recording.series import WheelSeries

VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
TEMPERATURE = "sensor_msgs/msg/Temperature"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"

#: channel (last topic name part) -> message type, INTERFACE.md "Topics, one set per wheel".
CHANNEL_TYPES: dict[str, str] = {
    "slip": VECTOR3_STAMPED,
    "load": WRENCH_STAMPED,
    "pressure": FLUID_PRESSURE,
    "temperature": TEMPERATURE,
    "velocity": TWIST_STAMPED,
    "forces": WRENCH_STAMPED,
    "measured_forces": WRENCH_STAMPED,
}
REQUIRED = ("slip", "load", "measured_forces")
OPTIONAL = ("pressure", "temperature", "velocity")
#: channel -> (WheelSeries attribute, column of the decoded fields) for single-value channels.
_OPTIONAL_FIELDS = {"pressure": ("p", 0), "temperature": ("T", 0), "velocity": ("Vx", 0)}
#: WheelSeries attributes of the measured wrench, in WrenchStamped field order.
_FORCE_FIELDS = ("Fx", "Fy", "Fz_meas", "Mx", "My", "Mz")
_NS = 1_000_000_000


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


def _storage_of(path: Path) -> str:
    return "sqlite3" if path.suffix == ".db3" else "mcap"


def _open_storage_file(path: Path):
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    reader = (Sqlite3Reader if path.suffix == ".db3" else McapReader)(path)
    reader.open()
    return reader


class _Collector:
    """Gathers (topic, log time, bytes) from rosbags' iterators into ``RawTopic`` arrays."""

    def __init__(self, select: Callable[[str], bool]) -> None:
        self.select = select
        self.count = 0
        self.parts: dict[str, tuple[str, list, list]] = {}

    def add(self, messages: Iterable) -> None:
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
        out = {}
        for topic, (msgtype, data, log_ns) in self.parts.items():
            buf, starts, lens = cdr.join(data)
            log = np.asarray(log_ns, np.int64)
            order = np.argsort(log, kind="stable")
            out[topic] = RawTopic(msgtype, buf, starts[order], lens[order], log[order])
        return out


def _topic_table(connections) -> dict[str, tuple[str, int]]:
    table: dict[str, tuple[str, int]] = {}
    for c in connections:
        old = table.get(c.topic, (c.msgtype, 0))
        table[c.topic] = (c.msgtype, old[1] + c.msgcount)
    return table


def _read_storage_file(path: Path, select) -> tuple[dict[str, RawTopic], int, int, dict]:
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


def _read_files(files: Sequence[Path], select) -> tuple[dict[str, RawTopic], int, dict]:
    parts, count, table = [], 0, {}
    for file in files:
        found, n, _, file_table = _read_storage_file(file, select)
        parts.append(found)
        count += n
        for t, (mt, c) in file_table.items():
            table[t] = (mt, table.get(t, (mt, 0))[1] + c)
    return _merge(parts), count, table


def _read_dir(path: Path, select) -> RawBag:
    from rosbags.rosbag2 import Reader

    simple = _mcap_files(path)
    if simple is not None:
        topics, count, table = _read_files(simple[0], select)
        return RawBag(path, "mcap", topics, table, simple[1], count)

    with Reader(path) as reader:  # validates metadata.yaml (version, files, plugin)
        plugin = type(reader.storage.storages[0]).__name__ if reader.storage.storages else ""
        storage = "sqlite3" if "Sqlite" in plugin else "mcap"
        all_topics = _topic_table(reader.connections)
        announced = reader.message_count
        compressed = reader.compression_mode
        files = [Path(s.path) for s in reader.storage.storages]
        if storage == "mcap" and not compressed:
            collector = None
        else:
            collector = _Collector(select)
            collector.add(reader.messages())
    if collector is not None and (collector.count >= announced or compressed):
        return RawBag(path, storage, collector.topics(), all_topics, announced, collector.count)
    # Uncompressed MCAP: read the files through their own index (fast). Also the fallback when
    # rosbags' metadata.yaml route yields too few messages: it matches the metadata's topics to
    # the storage file's including QoS, and yields nothing for a topic whose QoS differ.
    topics, count, _ = _read_files(files, select)
    return RawBag(path, storage, topics, all_topics, announced, count, collector is not None)


def _read_file(path: Path, select) -> RawBag:
    topics, count, announced, table = _read_storage_file(path, select)
    return RawBag(path, _storage_of(path), topics, table, announced, count)


def read_raw(path: str | os.PathLike, select: Callable[[str], bool] | None = None) -> RawBag:
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


# --------------------------------------------------------------------------- alignment


def latest_at_or_before(stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the last of ``stamps`` (sorted) that is <= each ``t``; -1 where none."""
    return np.searchsorted(stamps, t, side="right") - 1


def nearest(stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the entry of ``stamps`` (sorted, non-empty) nearest to each ``t``.

    An exact match wins; of two at the same distance, the earlier one.
    """
    j = np.searchsorted(stamps, t, side="left")
    after = np.minimum(j, len(stamps) - 1)
    before = np.maximum(j - 1, 0)
    take_after = np.abs(stamps[after] - t) < np.abs(t - stamps[before])
    return np.where(take_after, after, before)


def find_wheels(topics: Iterable[str]) -> tuple[list[str], dict[str, list[str]]]:
    """Complete wheel prefixes, and incomplete ones with their missing required channels."""
    topics = set(topics)
    prefixes = {t[: -len("/" + c)] for t in topics for c in REQUIRED if t.endswith("/" + c)}
    complete, partial = [], {}
    for p in sorted(prefixes):
        missing = [c for c in REQUIRED if f"{p}/{c}" not in topics]
        if missing:
            partial[p] = missing
        else:
            complete.append(p)
    return complete, partial


def _align(bag: RawBag, prefix: str) -> WheelSeries:
    ch = {
        c: decode_topic(bag, f"{prefix}/{c}")
        for c in (*REQUIRED, *OPTIONAL)
        if f"{prefix}/{c}" in bag.topics
    }
    for c in REQUIRED:
        if c not in ch or len(ch[c].stamp_ns) == 0:
            raise RecordingError(f"{bag.path}: wheel {prefix}: topic {prefix}/{c} has no messages")
    slip_ns = ch["slip"].stamp_ns
    i_load = latest_at_or_before(ch["load"].stamp_ns, slip_ns)
    keep = i_load >= 0  # slip is sorted, so the dropped samples are the leading ones
    dropped = int(len(keep) - keep.sum())
    if not keep.any():
        raise RecordingError(
            f"{bag.path}: wheel {prefix}: no {prefix}/slip message at or after the first "
            f"{prefix}/load message"
        )
    t_ns = slip_ns[keep]
    slip = ch["slip"].values[keep]
    kw: dict = {
        "prefix": prefix,
        "t": t_ns / _NS,
        "kappa": slip[:, 0],
        "alpha": slip[:, 1],
        "gamma": slip[:, 2],
        "Fz": ch["load"].values[i_load[keep], 2],
    }
    backfilled = {}
    for c, (name, col) in _OPTIONAL_FIELDS.items():
        if c in ch and len(ch[c].stamp_ns):
            i = latest_at_or_before(ch[c].stamp_ns, t_ns)
            backfilled[name] = int((i < 0).sum())
            kw[name] = ch[c].values[np.maximum(i, 0), col]  # before the first: its first value
    mf = ch["measured_forces"]
    j = nearest(mf.stamp_ns, t_ns)
    dt = np.abs(mf.stamp_ns[j] - t_ns)
    for k, name in enumerate(_FORCE_FIELDS):
        kw[name] = mf.values[j, k]
    kw["meta"] = {
        "source": str(bag.path),
        "storage": bag.storage,
        "t_ns": t_ns,
        "n_slip": len(slip_ns),
        "dropped_no_load": dropped,
        "backfilled": backfilled,
        "forces_exact": int((dt == 0).sum()),
        "forces_max_dt_s": float(dt.max() / _NS) if len(dt) else 0.0,
        "reader_fallback": bag.fallback,
        "messages_read": bag.messages_read,
        "messages_announced": bag.message_count,
    }
    return WheelSeries(**kw)


def read_recording(
    path: str | os.PathLike, *, wheels: Sequence[str] | None = None
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
        return channel in (*REQUIRED, *OPTIONAL) and (wanted is None or prefix in wanted)

    return wheels_from_raw(read_raw(path, select), wheels)


def wheels_from_raw(bag: RawBag, wheels: Sequence[str] | None = None) -> dict[str, WheelSeries]:
    """``read_recording`` on an already read ``RawBag`` (which must hold the wheel topics)."""
    path = bag.path
    wanted = set(wheels) if wheels is not None else None
    complete, partial = find_wheels(bag.all_topics)
    if wanted is not None:
        for p in sorted(wanted - set(complete)):
            missing = partial.get(p, list(REQUIRED))
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


# --------------------------------------------------------------------------- writing


def _stamps_ns(w: WheelSeries) -> np.ndarray:
    """Exact slip stamps [ns]: ``meta["t_ns"]`` if it still matches ``t``, else from ``t``."""
    t_ns = w.meta.get("t_ns") if isinstance(w.meta, dict) else None
    if t_ns is not None and len(t_ns) == len(w.t):
        t_ns = np.asarray(t_ns, np.int64)
        if np.all(np.abs(t_ns / _NS - w.t) <= 1e-6):
            return t_ns
    return np.round(np.asarray(w.t) * _NS).astype(np.int64)


def decimate_mask(t_ns: np.ndarray, rate_hz: float | None) -> np.ndarray:
    """Samples to keep so a channel is logged at most at ``rate_hz``: the first of each period."""
    if rate_hz is None:
        return np.ones(len(t_ns), bool)
    if not rate_hz > 0 or not np.isfinite(rate_hz):
        raise ValueError(f"channel rate must be a positive number of Hz, got {rate_hz}")
    if len(t_ns) == 0:
        return np.ones(0, bool)
    period = (t_ns - t_ns[0]) // round(_NS / rate_hz)
    mask = np.ones(len(t_ns), bool)
    mask[1:] = period[1:] != period[:-1]
    return mask


def _wheel_channels(w: WheelSeries) -> dict[str, tuple[str, np.ndarray]]:
    """channel -> (type, (n, k) values) of the topics a wheel writes (None channels skipped)."""
    n = len(w)
    zeros = np.zeros(n)
    out = {
        "slip": (VECTOR3_STAMPED, np.column_stack([w.kappa, w.alpha, w.gamma])),
        "load": (WRENCH_STAMPED, np.column_stack([zeros, zeros, w.Fz, zeros, zeros, zeros])),
    }
    if w.p is not None:
        out["pressure"] = (FLUID_PRESSURE, np.column_stack([w.p, zeros]))
    if w.T is not None:
        out["temperature"] = (TEMPERATURE, np.column_stack([w.T, zeros]))
    if w.Vx is not None:
        twist = np.column_stack([w.Vx, zeros, zeros, zeros, zeros, zeros])
        out["velocity"] = (TWIST_STAMPED, twist)
    Fz = w.Fz_meas if w.Fz_meas is not None else w.Fz
    forces = [w.Fx, w.Fy, Fz, w.Mx, w.My, w.Mz]
    if any(f is not None for f in (w.Fx, w.Fy, w.Mx, w.My, w.Mz, w.Fz_meas)):
        cols = [f if f is not None else np.full(n, np.nan) for f in forces]
        out["measured_forces"] = (WRENCH_STAMPED, np.column_stack(cols))
    return out


class BagWriter:
    """Streams messages into a new bag, atomically: a temp folder beside ``path``, renamed on
    ``close()``; ``abort()`` (or an exception inside ``with``) leaves ``path`` untouched.

    ``path`` with a ``.mcap`` / ``.db3`` suffix becomes a lone storage file, else a rosbag2
    folder (metadata.yaml version 9).
    """

    def __init__(
        self, path: str | os.PathLike, *, overwrite: bool = False, storage: str = "mcap"
    ) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = Path(path)
        self.lone = self.path.suffix in (".mcap", ".db3")
        self.storage = _storage_of(self.path) if self.lone else storage
        if self.storage not in ("mcap", "sqlite3"):
            raise ValueError(f"storage must be 'mcap' or 'sqlite3', got {self.storage!r}")
        if (self.path.exists() or self.path.is_symlink()) and not overwrite:
            raise FileExistsError(f"{self.path}: exists already (use overwrite=True / --force)")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.tmpdir = Path(
            tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        )
        self.bag = self.tmpdir / (self.path.stem if self.lone else self.path.name)
        plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[self.storage]
        self.writer = Writer(self.bag, version=9, storage_plugin=plugin)
        self.connections: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self.closed = False
        try:
            self.writer.open()
        except BaseException:
            shutil.rmtree(self.tmpdir, ignore_errors=True)
            raise

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declare a topic (once; its type must be in the ROS 2 Jazzy typestore)."""
        if topic in self.connections:
            raise ValueError(f"topic {topic} added twice")
        self.connections[topic] = self.writer.add_connection(
            topic, msgtype, typestore=cdr.typestore()
        )
        self.counts[topic] = 0

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None:
        """One message: CDR bytes, log time [ns] (this package uses the header stamp)."""
        self.writer.write(self.connections[topic], int(log_ns), data)
        self.counts[topic] += 1

    def close(self) -> None:
        """Finish the bag and move it to ``path`` (replacing it if allowed at creation)."""
        if self.closed:
            return
        self.closed = True
        try:
            self.writer.close()
            ext = ".db3" if self.storage == "sqlite3" else ".mcap"
            new = self.bag / f"{self.bag.name}{ext}" if self.lone else self.bag
            replace_path(new, self.path)
        finally:
            shutil.rmtree(self.tmpdir, ignore_errors=True)

    def abort(self) -> None:
        """Drop everything written; ``path`` is left as it was."""
        if self.closed:
            return
        self.closed = True
        with contextlib.suppress(Exception):  # the temp folder is removed anyway
            self.writer.close()
        shutil.rmtree(self.tmpdir, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def write_topics(
    path: str | os.PathLike,
    topics: Mapping[str, tuple[str, np.ndarray, np.ndarray]],
    *,
    overwrite: bool = False,
    storage: str = "mcap",
    slip_last: bool = True,
) -> None:
    """Write decoded topics: ``{topic: (msgtype, stamp_ns, values (n, k))}``, log time = stamp.

    Messages go in stamp order; at equal stamps ``*/slip`` comes after the other topics (what a
    rig driver publishes first), then the order of ``topics``. MCAP is written by the
    vectorised writer of ``mcap_write``; sqlite3 through rosbags.
    """
    path = Path(path)
    names, types, stamps_of, rows_of = [], [], [], []
    for topic, (msgtype, stamp_ns, values) in topics.items():
        stamp_ns = np.asarray(stamp_ns, np.int64)
        names.append(topic)
        types.append(msgtype)
        stamps_of.append(stamp_ns)
        rows_of.append(cdr.encode_array(msgtype, stamp_ns, values))
    conn_idx = np.concatenate([np.full(len(s), i) for i, s in enumerate(stamps_of)])
    msg_idx = np.concatenate([np.arange(len(s)) for s in stamps_of])
    stamps = np.concatenate(stamps_of)
    prio = np.concatenate(
        [
            np.full(len(s), 1 if slip_last and t.endswith("/slip") else 0)
            for t, s in zip(names, stamps_of, strict=True)
        ]
    )
    order = np.lexsort((conn_idx, prio, stamps))
    lone = path.suffix in (".mcap", ".db3")
    if (_storage_of(path) if lone else storage) == "mcap":
        _write_fast_mcap(
            path, names, types, stamps_of, rows_of, (conn_idx[order], msg_idx[order]), overwrite
        )
        return
    with BagWriter(path, overwrite=overwrite, storage=storage) as writer:
        for topic, msgtype in zip(names, types, strict=True):
            writer.add_topic(topic, msgtype)
        for c, m in zip(conn_idx[order].tolist(), msg_idx[order].tolist(), strict=True):
            writer.write(names[c], int(stamps_of[c][m]), rows_of[c][m].tobytes())


def _rosbag2_metadata(file_name: str, names, types, stamps_of) -> dict:
    """metadata.yaml content (version 9), as rosbag2 / rosbags write it."""
    ts = cdr.typestore()
    all_stamps = [s for s in stamps_of if len(s)]
    start = int(min(s.min() for s in all_stamps)) if all_stamps else 0
    duration = int(max(s.max() for s in all_stamps)) - start if all_stamps else 0
    count = int(sum(len(s) for s in stamps_of))
    return {
        "version": 9,
        "storage_identifier": "mcap",
        "relative_file_paths": [file_name],
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": name,
                    "type": msgtype,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": [],
                    "type_description_hash": ts.hash_rihs01(msgtype),
                },
                "message_count": len(s),
            }
            for name, msgtype, s in zip(names, types, stamps_of, strict=True)
        ],
        "compression_format": "",
        "compression_mode": "",
        "files": [
            {
                "path": file_name,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": count,
            }
        ],
        "custom_data": None,
        "ros_distro": "jazzy",
    }


def _write_fast_mcap(path: Path, names, types, stamps_of, rows_of, order, overwrite) -> None:
    import yaml

    from tire_model_ros.recording.mcap_write import Batch, write_mcap

    if (path.exists() or path.is_symlink()) and not overwrite:
        raise FileExistsError(f"{path}: exists already (use overwrite=True / --force)")
    ts = cdr.typestore()
    batches = [
        Batch(name, msgtype, ts.generate_msgdef(msgtype, ros_version=2)[0], "[]", stamps, rows)
        for name, msgtype, stamps, rows in zip(names, types, stamps_of, rows_of, strict=True)
    ]
    lone = path.suffix == ".mcap"
    file_name = path.name if lone else f"{path.name}.mcap"
    info = _rosbag2_metadata(file_name, names, types, stamps_of)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        new = tmpdir / path.name
        if not lone:
            new.mkdir()
        target = new if lone else new / file_name
        write_mcap(target, batches, order, yaml.safe_dump(info, sort_keys=False).strip())
        if not lone:
            text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
            (new / "metadata.yaml").write_text(text)
        replace_path(new, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def _check_wheels(wheels: Sequence[WheelSeries]) -> None:
    seen = set()
    for w in wheels:
        if not isinstance(w, WheelSeries):
            raise ValueError(f"write_recording: expected WheelSeries, got {type(w).__name__}")
        if w.prefix in seen:
            raise ValueError(f"write_recording: wheel prefix {w.prefix!r} given twice")
        if (w.prefix and not w.prefix.startswith("/")) or w.prefix.endswith("/"):
            raise ValueError(
                f"write_recording: prefix {w.prefix!r} must start with '/' and not end with '/'"
            )
        if len(w) == 0:
            raise ValueError(f"write_recording: wheel {w.prefix!r} has no samples")
        if not np.all(np.isfinite(w.t)):
            raise ValueError(f"write_recording: wheel {w.prefix!r}: t has non-finite values")
        seen.add(w.prefix)
    if not wheels:
        raise ValueError("write_recording: no wheels to write")


def write_recording(
    path: str | os.PathLike,
    wheels: Sequence[WheelSeries],
    *,
    overwrite: bool = False,
    storage: str = "mcap",
    rates: Mapping[str, float] | None = None,
) -> None:
    """Write wheels as a rosbag2 recording with the INTERFACE.md topics.

    Parameters
    ----------
    path : target. A ``.mcap`` / ``.db3`` suffix writes a lone storage file, anything else a
        rosbag2 folder (metadata.yaml version 9 + ``<name>.mcap`` / ``.db3``).
    wheels : one WheelSeries per wheel; ``header.stamp`` = log time = ``t``. Channels that are
        None are not written; measured_forces from Fx, Fy, Fz_meas (else Fz), Mx, My, Mz
        (written if any of them is given; a missing component is NaN).
    overwrite : replace an existing ``path`` (otherwise FileExistsError).
    storage : "mcap" (default) or "sqlite3". A lone-file suffix decides by itself.
    rates : channel -> maximum logging rate [Hz], e.g. ``{"pressure": 10, "temperature": 10}``
        (channels: load, pressure, temperature, velocity, measured_forces; slip is never
        decimated): the first sample of each 1/rate period is written.

    The bag is written into a temporary folder beside ``path`` and renamed into place.
    """
    rates = dict(rates or {})
    if unknown := set(rates) - {"load", *OPTIONAL, "measured_forces"}:
        raise ValueError(
            f"write_recording: rates for unknown channel(s) {sorted(unknown)} (slip is never "
            "decimated; channels: load, pressure, temperature, velocity, measured_forces)"
        )
    _check_wheels(wheels)
    topics = {}
    for w in wheels:
        t_ns = _stamps_ns(w)
        for channel, (msgtype, values) in _wheel_channels(w).items():
            keep = decimate_mask(t_ns, rates.get(channel))
            topics[f"{w.prefix}/{channel}"] = (msgtype, t_ns[keep], values[keep])
    write_topics(path, topics, overwrite=overwrite, storage=storage)
