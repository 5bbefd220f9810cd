"""Indexed MCAP message access without a Python loop per message.

An MCAP file written by rosbag2 (or rosbags) has chunks, and after each chunk one
MessageIndex record per channel: an array of (log_time u64, offset u64) pairs, the offset of
each Message record inside the chunk's uncompressed records. Those arrays are read with
``np.frombuffer``; a Message record is ``0x05, length u64, channel_id u16, sequence u32,
log_time u64, publish_time u64, data``, so every message's data start and length follow by
arithmetic.

The summary (schemas, channels, chunk indexes, statistics) is read with the ``mcap``
package's reader; the message indexes and records here. ``read_indexed`` returns None when
the file cannot be read this way (no summary or chunk index, counts that disagree with the
statistics); the caller then uses rosbags' own message iterator.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.cdr import _gather_words

if TYPE_CHECKING:
    from mcap.records import ChunkIndex

_MSG_HEADER = 1 + 8 + 22  # opcode, record length, channel_id..publish_time
Bytes = npt.NDArray[np.uint8]
Int64s = npt.NDArray[np.int64]
#: One topic's messages: (message type, data starts, data lengths, log times [ns]).
TopicIndex = tuple[str, Int64s, Int64s, Int64s]
#: (topic table: topic -> (type, count), messages announced, buffer, {topic: TopicIndex}).
Indexed = tuple[dict[str, tuple[str, int]], int, Bytes, dict[str, TopicIndex]]


def _chunk_records(filebuf: Bytes, chunk: ChunkIndex) -> Bytes:
    """The uncompressed records of one chunk (a view into ``filebuf`` when not compressed)."""
    from rosbags.rosbag2.storage_mcap import decompress

    start = chunk.chunk_start_offset + 9 + 40 + len(chunk.compression)
    data = filebuf[start : start + chunk.compressed_size]
    if not chunk.compression:
        if len(data) != chunk.uncompressed_size:
            raise ValueError("chunk size disagrees with its index")
        return data
    crc = int(filebuf[chunk.chunk_start_offset + 33 : chunk.chunk_start_offset + 37].view("<u4")[0])
    raw = decompress(data.tobytes(), chunk.compression, chunk.uncompressed_size, crc)
    return np.frombuffer(raw, np.uint8)


def _message_index(filebuf: Bytes, offset: int, channel_id: int) -> npt.NDArray[np.uint64]:
    """(log_time, offset) pairs of one MessageIndex record, shape (k, 2) uint64."""
    head = filebuf[offset : offset + 15]
    if len(head) < 15 or head[0] != 0x07:
        raise ValueError(f"no MessageIndex record at offset {offset}")
    if int(head[9:11].view("<u2")[0]) != channel_id:
        raise ValueError(f"MessageIndex at offset {offset} is for another channel")
    nbytes = int(head[11:15].view("<u4")[0])
    return filebuf[offset + 15 : offset + 15 + nbytes].view("<u8").reshape(-1, 2)


def read_indexed(path: Path, select: Callable[[str], bool]) -> Indexed | None:
    """Messages of the selected topics of an indexed MCAP file, or None (see module doc).

    Returns
    -------
    (topic_table, announced_count, buffer, {topic: (msgtype, starts, lens, log_ns)})
        ``topic_table``: every topic -> (type, message count); ``starts``/``lens`` locate each
        message's CDR bytes in ``buffer``; messages are in log-time order (ties: file order).
    """
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    if summary is None or not summary.chunk_indexes:
        return None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    msgtypes = {
        cid: summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas else ""
        for cid, ch in summary.channels.items()
    }
    filebuf = np.fromfile(path, np.uint8)
    wanted = {cid for cid, ch in summary.channels.items() if select(ch.topic)}
    segments: list[Bytes] = []
    base = 0
    parts: dict[int, list[tuple[Int64s, Int64s]]] = {cid: [] for cid in wanted}
    counts = dict.fromkeys(summary.channels, 0)
    for chunk in chunks:
        records = _chunk_records(filebuf, chunk)
        for cid, moff in chunk.message_index_offsets.items():
            if cid not in counts:
                raise ValueError(f"message index for unknown channel {cid}")
            index = _message_index(filebuf, moff, cid)
            counts[cid] += len(index)
            if cid in wanted and len(index):
                off = index[:, 1].astype(np.int64)
                _check_messages(records, off, cid)
                parts[cid].append((off + base, index[:, 0].astype(np.int64)))
        segments.append(records)
        base += len(records)
    total = sum(counts.values())
    stats = summary.statistics
    if stats is not None and stats.message_count != total:
        return None  # messages outside the index (or a broken index): read it all
    buffer = segments[0] if len(segments) == 1 else np.concatenate(segments)
    table: dict[str, tuple[str, int]] = {}
    for cid, ch in summary.channels.items():
        old = table.get(ch.topic, (msgtypes[cid], 0))
        if old[0] != msgtypes[cid]:
            raise ValueError(f"topic {ch.topic} has two message types")
        table[ch.topic] = (msgtypes[cid], old[1] + counts[cid])
    found: dict[str, tuple[str, list[Int64s], list[Int64s]]] = {}
    for cid in sorted(wanted):
        if parts[cid]:
            entry = found.setdefault(summary.channels[cid].topic, (msgtypes[cid], [], []))
            entry[1].extend(p[0] for p in parts[cid])
            entry[2].extend(p[1] for p in parts[cid])
    result: dict[str, TopicIndex] = {}
    for topic, (msgtype, recs, logs) in found.items():
        rec, log_ns = np.concatenate(recs), np.concatenate(logs)
        order = np.lexsort((rec, log_ns))
        rec, log_ns = rec[order], log_ns[order]
        lens = _u64(buffer, rec + 1).astype(np.int64) - 22
        result[topic] = (msgtype, rec + _MSG_HEADER, lens, log_ns)
    return table, total, buffer, result


def _u64(buf: Bytes, offsets: Int64s) -> npt.NDArray[np.uint64]:
    return _gather_words(buf, offsets, 1, "<u8")[:, 0]


def _check_messages(records: Bytes, off: Int64s, cid: int) -> None:
    """Every indexed offset must hold a Message record of this channel inside the chunk."""
    if off.size == 0:
        return
    if off.min() < 0 or off.max() + _MSG_HEADER > len(records):
        raise ValueError("message index points outside its chunk")
    if not np.all(records[off] == 0x05):
        raise ValueError("message index points at a record that is not a message")
    size = _u64(records, off + 1).astype(np.int64)
    chan = _gather_words(records, off + 9, 1, "<u2")[:, 0]
    if np.any(size < 22) or np.any(off + 9 + size > len(records)) or np.any(chan != cid):
        raise ValueError("message index and message records disagree")
