"""Reading recordings (rosbag2 bags): raw messages, topic decoding, aligned ``WheelSeries``.

Formats read: a rosbag2 folder (metadata.yaml + .mcap or .db3, CDR), a lone ``.mcap`` or
``.db3`` file. A wheel is a prefix P with ``P/slip``, ``P/load`` and ``P/measured_forces``;
other topics are ignored. Receive (log) times order messages of equal stamp (log time, then
file order) and are used for nothing else; the samples follow the alignment rule of
:mod:`.align`.

Storage files are read by :mod:`.raw`, folders by :mod:`.folder`. MCAP files are read by this
package (``mcap_scan.read_mcap``): through their chunk and message indexes with numpy
(``mcap_index``), else record by record; every CRC the file carries is checked. CDR is
decoded with fixed layouts (``cdr``; rosbags' deserialiser is the reference and the fallback
for odd messages). sqlite3 bags go through rosbags; when its metadata.yaml
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
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tire_model_ros.recording import cdr
from tire_model_ros.recording.align import align_wheel
from tire_model_ros.recording.errors import Damage, DamagedBagError, RecordingError
from tire_model_ros.recording.folder import read_folder, storage_files_in
from tire_model_ros.recording.raw import RawBag, RawTopic, Select, read_file, storage_of
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.vocabulary import CHANNEL_TYPES, OPTIONAL_CHANNELS, REQUIRED_CHANNELS

__all__ = [
    "Channel",
    "Damage",
    "DamagedBagError",
    "RawBag",
    "RawTopic",
    "RecordingError",
    "decode_topic",
    "find_wheels",
    "read_raw",
    "read_recording",
    "storage_of",
    "wheel_select",
    "wheels_from_raw",
]


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
            files = storage_files_in(path)
            hint = f"; it holds {len(files)} storage file(s): --salvage reads them" if files else ""
            raise RecordingError(f"{path}: not a rosbag2 folder (no metadata.yaml){hint}")
        reader = read_folder
    elif path.suffix in (".mcap", ".db3"):
        reader = read_file
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
