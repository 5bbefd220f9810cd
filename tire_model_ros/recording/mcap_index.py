"""Indexed MCAP message access without a Python loop per message, with every CRC checked.

An MCAP file written by rosbag2 (or rosbags, or this package) has chunks, and after each chunk
one MessageIndex record per channel: an array of (log_time u64, offset u64) pairs, the offset
of each Message record inside the chunk's uncompressed records. Those arrays are read with
``np.frombuffer``; a Message record is ``0x05, length u64, channel_id u16, sequence u32,
log_time u64, publish_time u64, data``, so every message's data start and length follow by
arithmetic.

The summary (schemas, channels, chunk indexes, statistics) is read with the ``mcap``
package's reader once its CRC holds; the message indexes and records here. Checked on the way
(:mod:`.mcap_check`): the summary CRC, the data section CRC (when written: it covers every
chunk at once, so the chunks' own CRCs are computed only when it is absent or fails, to name
the damaged ones), every message index against the records it points at (record type,
channel, log time). ``read_indexed`` returns None when the file has no usable index (not
closed, no summary or chunk index, counts that disagree with the statistics): the linear scan
of :mod:`.mcap_scan` reads it then.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording import mcap_check
from tire_model_ros.recording.cdr import _gather_words
from tire_model_ros.recording.errors import Damage, DamagedBagError

if TYPE_CHECKING:
    from mcap.records import ChunkIndex
    from mcap.summary import Summary

_MSG_HEADER = 1 + 8 + 22  # opcode, record length, channel_id..publish_time
_LOG_AT = 1 + 8 + 2 + 4  # log_time's offset in a Message record
Bytes = npt.NDArray[np.uint8]
Int64s = npt.NDArray[np.int64]
#: One topic's messages: (message type, data starts, data lengths, log times [ns]).
TopicIndex = tuple[str, Int64s, Int64s, Int64s]
#: Per channel id: pieces of (data starts, data lengths, log times [ns]).
Pieces = dict[int, list[tuple[Int64s, Int64s, Int64s]]]


@dataclass(frozen=True)
class Declared:
    """Schemas and channels of a file: schema id -> (type, definition), channel id -> (topic,
    schema id)."""

    schemas: dict[int, tuple[str, str]]
    channels: dict[int, tuple[str, int]]

    def msgtype(self, cid: int) -> str:
        return self.schemas.get(self.channels[cid][1], ("", ""))[0]

    def topic(self, cid: int) -> str:
        """The channel's topic (an undeclared id as ``channel N``)."""
        return self.channels[cid][0] if cid in self.channels else f"channel {cid}"

    def topics(self, cids: Iterable[int]) -> tuple[str, ...]:
        """Sorted topics of the channel ids in ``cids``."""
        return tuple(sorted({self.topic(c) for c in cids}))


@dataclass
class McapContent:
    """What was read from one MCAP file.

    ``table``: every topic -> (type, messages found); ``topics``: the selected ones' messages,
    in log-time order (ties: file order), located in ``buffer``; ``msgdefs``: type ->
    definition text; ``damages``: what was skipped (salvage) or noted.
    """

    table: dict[str, tuple[str, int]]
    announced: int
    buffer: Bytes
    topics: dict[str, TopicIndex]
    msgdefs: dict[str, str]
    damages: list[Damage]


@dataclass(frozen=True)
class Rescan:
    """The index cannot be trusted (salvage): scan the file, with what the summary declares
    when its CRC held."""

    damage: Damage
    declared: Declared | None


def assemble(
    declared: Declared,
    pieces: Pieces,
    counts: dict[int, int],
    buffer: Bytes,
    announced: int | None,
    damages: list[Damage],
) -> McapContent:
    """The selected channels' ``pieces`` as topics in log-time order, and the topic table of
    every channel with its ``counts``; ``announced`` None: the count found."""
    table: dict[str, tuple[str, int]] = {}
    found: dict[str, tuple[str, list[tuple[Int64s, Int64s, Int64s]]]] = {}
    for cid in sorted(declared.channels):
        topic, msgtype = declared.channels[cid][0], declared.msgtype(cid)
        old = table.get(topic, (msgtype, 0))
        if old[0] != msgtype:
            raise ValueError(f"topic {topic} has two message types")
        table[topic] = (msgtype, old[1] + counts.get(cid, 0))
        if pieces.get(cid):
            found.setdefault(topic, (msgtype, []))[1].extend(pieces[cid])
    topics: dict[str, TopicIndex] = {}
    for topic, (msgtype, parts) in found.items():
        starts, lens, log_ns = (np.concatenate([p[k] for p in parts]) for k in range(3))
        order = np.lexsort((starts, log_ns))
        topics[topic] = (msgtype, starts[order], lens[order], log_ns[order])
    total = sum(n for _, n in table.values())
    msgdefs = {name: text for name, text in declared.schemas.values()}
    return McapContent(
        table, total if announced is None else announced, buffer, topics, msgdefs, damages
    )


def _chunk_records(filebuf: Bytes, chunk: ChunkIndex) -> Bytes:
    """The uncompressed records of one chunk (a view into ``filebuf`` when not compressed)."""
    from rosbags.rosbag2.storage_mcap import decompress

    start = chunk.chunk_start_offset + 9 + 40 + len(chunk.compression)
    data = filebuf[start : start + chunk.compressed_size]
    if not chunk.compression:
        if len(data) != chunk.uncompressed_size:
            raise ValueError("chunk size disagrees with its index")
        return data
    # the CRC is compared by the caller (0: no CRC check here)
    raw = decompress(data.tobytes(), chunk.compression, chunk.uncompressed_size, 0)
    return np.frombuffer(raw, np.uint8)


def _stored_crc(filebuf: Bytes, chunk: ChunkIndex) -> int:
    at = chunk.chunk_start_offset + 9 + 24
    return int(filebuf[at : at + 4].view("<u4")[0])


def _message_index(filebuf: Bytes, offset: int, channel_id: int) -> npt.NDArray[np.uint64]:
    """(log_time, offset) pairs of one MessageIndex record, shape (k, 2) uint64."""
    head = filebuf[offset : offset + 15]
    if len(head) < 15 or head[0] != 0x07:
        raise ValueError(f"no MessageIndex record at offset {offset}")
    if int(head[9:11].view("<u2")[0]) != channel_id:
        raise ValueError(f"MessageIndex at offset {offset} is for another channel")
    nbytes = int(head[11:15].view("<u4")[0])
    if nbytes % 16 or offset + 15 + nbytes > len(filebuf):
        raise ValueError(f"MessageIndex at offset {offset} has a bad length")
    return filebuf[offset + 15 : offset + 15 + nbytes].view("<u8").reshape(-1, 2)


def _summary(path: Path) -> Summary | None:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return make_reader(f).get_summary()


def _declared(summary: Summary) -> Declared:
    schemas = {
        sid: (s.name, s.data.decode("utf-8", "replace")) for sid, s in summary.schemas.items()
    }
    channels = {cid: (ch.topic, ch.schema_id) for cid, ch in summary.channels.items()}
    return Declared(schemas, channels)


def _lost(filebuf: Bytes, chunk: ChunkIndex, declared: Declared) -> dict[str, int] | None:
    """Messages per topic of a skipped chunk, by its message indexes (None: unreadable)."""
    lost: dict[str, int] = {}
    try:
        for cid, moff in chunk.message_index_offsets.items():
            topic = declared.topic(cid)
            lost[topic] = lost.get(topic, 0) + len(_message_index(filebuf, moff, cid))
    except ValueError:
        return None
    return lost


class _Reader:
    """One pass over the chunks of a closed, indexed file (see ``read_indexed``): the chunks
    one by one (CRCs), then every message index at once (numpy, whatever the chunk count)."""

    def __init__(
        self, file: Path, filebuf: Bytes, summary: Summary, select: Callable[[str], bool]
    ) -> None:
        self.file, self.filebuf, self.summary = file, filebuf, summary
        self.declared = _declared(summary)
        self.wanted = {cid for cid, (topic, _) in self.declared.channels.items() if select(topic)}
        self.pieces: Pieces = {}
        self.counts = dict.fromkeys(self.declared.channels, 0)
        self.segments: list[Bytes] = []
        self.index_at: list[tuple[int, int, int]] = []  # (record offset, channel, segment)

    def chunk(self, chunk: ChunkIndex, verified: bool) -> Damage | None:
        """Take one chunk's records; a damaged chunk is returned (and skipped)."""
        offset = chunk.chunk_start_offset
        try:
            records = _chunk_records(self.filebuf, chunk)
            stored = _stored_crc(self.filebuf, chunk)
            reason = None if verified else mcap_check.chunk_crc_reason(stored, records)
        except Exception as exc:  # decompression and size errors of a damaged chunk
            reason = f"unreadable ({type(exc).__name__}: {exc})"
        if reason is not None:
            topics = self.declared.topics(chunk.message_index_offsets)
            lost = _lost(self.filebuf, chunk, self.declared)
            return Damage(self.file, "chunk", reason, offset, topics, lost)
        seg = len(self.segments)
        self.index_at.extend((moff, cid, seg) for cid, moff in chunk.message_index_offsets.items())
        self.segments.append(records)
        return None

    def buffer(self) -> Bytes:
        if len(self.segments) == 1:
            return self.segments[0]
        return np.concatenate(self.segments) if self.segments else np.zeros(0, np.uint8)

    def messages(self, buffer: Bytes) -> None:
        """Read every message index of the chunks taken, check each entry against the record
        it points at (a Message of that channel inside its chunk, with the same log time),
        count and locate the messages. Raises ``_IndexDamageError`` naming the first index
        that disagrees."""
        if not self.index_at:
            return
        # channel by channel (chunks in file order within one): each channel's entries end
        # up contiguous, and are split off without a mask per channel
        at, cid, seg = (
            np.array(c, np.int64) for c in zip(*sorted(self.index_at, key=_by_channel), strict=True)
        )
        nbytes = self._index_heads(at, cid)
        if len(buffer) < _MSG_HEADER:
            self._index_damage(int(at[0]), int(cid[0]), "message index of empty chunks")
        owner = np.repeat(np.arange(len(at)), nbytes // 16)
        # each index's pairs are contiguous in the file: views, joined once
        views = (
            self.filebuf[a + 15 : a + 15 + n]
            for a, n in zip(at.tolist(), nbytes.tolist(), strict=True)
        )
        pairs = np.concatenate(list(views)).view("<u8").reshape(-1, 2)
        log_ns, local = pairs[:, 0], pairs[:, 1].astype(np.int64)  # > 2**63: negative, refused
        seg_len = np.array([len(r) for r in self.segments], np.int64)
        end = np.cumsum(seg_len)[seg][owner]  # where each entry's chunk ends in ``buffer``
        pos = local + (end - seg_len[seg][owner])
        # a Message record's header must fit in its chunk; where not, look at byte 0 instead
        good = (local >= 0) & (pos + _MSG_HEADER <= end)
        pos[~good] = 0
        head = _message_heads(buffer, pos)
        size = head["len"].astype(np.int64)
        good &= (head["op"] == 0x05) & (size >= 22) & (size <= end - pos - 9)
        good &= (head["chan"] == cid[owner]) & (head["log"] == log_ns)
        if not good.all():
            bad = int(owner[np.argmin(good)])
            reason = "message index and message records disagree"
            self._index_damage(int(at[bad]), int(cid[bad]), reason)
        per_channel = np.bincount(cid, weights=nbytes // 16, minlength=max(self.counts) + 1)
        stop = 0
        for c in sorted(self.counts):
            start, stop = stop, stop + int(per_channel[c])
            self.counts[c] = stop - start
            if c in self.wanted and stop > start:
                lens = size[start:stop] - 22
                self.pieces[c] = [
                    (pos[start:stop] + _MSG_HEADER, lens, log_ns[start:stop].astype(np.int64))
                ]

    def _index_heads(self, at: Int64s, cid: Int64s) -> Int64s:
        """Byte length of each MessageIndex's pairs; its header checked (type, channel)."""
        fb = self.filebuf
        ok = at + 15 <= len(fb)
        head = np.where(ok, at, 0)
        ok &= fb[head] == 0x07
        ok &= _gather_words(fb, head + 9, 1, "<u2")[:, 0] == cid
        nbytes = _gather_words(fb, head + 11, 1, "<u4")[:, 0].astype(np.int64)
        ok &= (nbytes % 16 == 0) & (head + 15 + nbytes <= len(fb))
        ok &= np.isin(cid, list(self.counts))
        if not ok.all():
            bad = int(np.argmin(ok))
            self._index_damage(
                int(at[bad]),
                int(cid[bad]),
                "not a message index of a declared channel, or a bad length",
            )
        return nbytes

    def _index_damage(self, at: int, cid: int, reason: str) -> None:
        damage = Damage(self.file, "message index", reason, at, self.declared.topics([cid]))
        raise _IndexDamageError(damage)


def _by_channel(entry: tuple[int, int, int]) -> tuple[int, int]:
    """Sort key of a message index (offset, channel, segment): channel, then segment."""
    return entry[1], entry[2]


class _IndexDamageError(Exception):
    def __init__(self, damage: Damage) -> None:
        super().__init__(damage.describe())
        self.damage = damage


def read_indexed(
    file: Path, filebuf: Bytes, select: Callable[[str], bool], salvage: bool = False
) -> McapContent | Rescan | None:
    """Messages of the selected topics of a closed, indexed MCAP file.

    Returns
    -------
    McapContent, or None when the file has no usable index (the caller scans it), or
    ``Rescan`` (``salvage`` only) when its summary, a message index or the data section
    between the chunks is damaged: the caller scans the chunks themselves.

    Raises
    ------
    DamagedBagError
        (not ``salvage``) a CRC that fails or an index that disagrees with its records,
        naming the file, the byte offset and the topics.
    """
    ends = mcap_check.find_ends(filebuf)
    if ends is None:
        return None
    bad = mcap_check.summary_damage(file, filebuf, ends)
    if bad is not None:
        if not salvage:
            raise DamagedBagError([bad])
        return Rescan(bad, None)
    try:
        summary = _summary(file)
    except Exception as exc:  # a summary without CRC, damaged: the mcap package's errors
        if not salvage:
            raise
        reason = f"unreadable ({type(exc).__name__}: {exc})"
        return Rescan(Damage(file, "summary", reason, ends.summary_start), None)
    if summary is None or not summary.chunk_indexes:
        return None
    data_ok = mcap_check.data_section_ok(filebuf, ends)
    reader = _Reader(file, filebuf, summary, select)
    declared = reader.declared if ends.summary_crc else None
    damaged: list[Damage] = []
    for chunk in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        damage = reader.chunk(chunk, verified=bool(data_ok))
        if damage is not None:
            damaged.append(damage)
    if damaged and not salvage:
        raise DamagedBagError(damaged)
    buffer = reader.buffer()
    try:
        reader.messages(buffer)
    except _IndexDamageError as exc:
        if not salvage:
            raise DamagedBagError([exc.damage]) from None
        return Rescan(exc.damage, declared)
    if data_ok is False and not damaged:
        if not salvage:
            raise DamagedBagError([mcap_check.data_section_damage(file, ends)])
        return Rescan(mcap_check.data_section_damage(file, ends), declared)
    stats = summary.statistics
    total = sum(reader.counts.values())
    if not damaged and stats is not None and stats.message_count != total:
        return None  # messages outside the index (or a broken index): read it all
    announced = stats.message_count if stats is not None else None
    pieces, counts = reader.pieces, reader.counts
    return assemble(reader.declared, pieces, counts, buffer, announced, damaged)


#: The fixed part of a Message record, as laid out in the file.
_HEAD = np.dtype(
    [("op", "u1"), ("len", "<u8"), ("chan", "<u2"), ("seq", "<u4"), ("log", "<u8"), ("pub", "<u8")]
)


def _message_heads(buf: Bytes, offsets: Int64s) -> npt.NDArray[np.void]:
    """The Message record headers at ``offsets`` of ``buf``: one 31-byte gather per message
    through a 1-byte-stride view (all offsets at least 31 bytes before the end)."""
    # gathering opaque 31-byte items is ~4x faster than gathering the structured dtype
    size = _HEAD.itemsize
    window = np.ndarray((len(buf) - size + 1,), f"V{size}", buffer=buf, strides=(1,))
    heads: npt.NDArray[np.void] = window[offsets].view(_HEAD)
    return heads
