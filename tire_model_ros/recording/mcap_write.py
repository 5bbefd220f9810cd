"""Writing MCAP files (ros2 profile): ``McapFile`` lays out the records with every CRC, and
``write_mcap`` writes batches of fixed-size CDR messages vectorised.

rosbags' writer costs ~20 us of Python per message and writes no CRC; here the Message records
of a whole batch are laid out with numpy (one structured record per message, placed with a
1-byte-stride view), so writing 1e5 messages takes a fraction of a second. The file layout
follows the MCAP spec (https://mcap.dev/spec) as rosbag2 and rosbags write it: Header; Schema
and Channel records; uncompressed Chunks of ~1 MiB, each with the CRC32 of its records and
followed by one MessageIndex per channel; a rosbag2 Metadata record; DataEnd with the CRC32 of
the data section; the summary (Schemas, Channels, ChunkIndexes, MetadataIndex, Statistics)
with SummaryOffsets; Footer with the CRC32 of the summary. The streaming writer of
:mod:`.mcap_stream` writes through ``McapFile`` too.

No ROS import here. Tested by reading back with the ``mcap`` package (CRCs validated) and
rosbags.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import BinaryIO

import numpy as np
import numpy.typing as npt

MAGIC = b"\x89MCAP0\r\n"
CHUNK_BYTES = 1 << 20
_MSG_HEADER = 31  # opcode u8, length u64, channel u16, sequence u32, log_time u64, publish u64
#: Per channel, (log time [ns], offset of the Message record in its chunk's records), (k, 2).
Pairs = npt.NDArray[np.uint64]


@dataclass
class Batch:
    """Messages of one topic: CDR rows of equal size, log times [ns]."""

    topic: str
    msgtype: str
    msgdef: str  # ros2msg text of the type (schema data)
    qos: str  # offered_qos_profiles metadata of the channel
    log_ns: np.ndarray  # (n,) int64
    rows: np.ndarray  # (n, L) uint8


def _u16(x: int) -> bytes:
    return int(x).to_bytes(2, "little")


def _u32(x: int) -> bytes:
    return int(x).to_bytes(4, "little")


def _u64(x: int) -> bytes:
    return int(x).to_bytes(8, "little")


def _str(s: str | bytes) -> bytes:
    b = s.encode() if isinstance(s, str) else s
    return _u32(len(b)) + b


def _map(items: Sequence[tuple[bytes, bytes]]) -> bytes:
    body = b"".join(k + v for k, v in items)
    return _u32(len(body)) + body


def _record(op: int, body: bytes) -> bytes:
    return bytes([op]) + _u64(len(body)) + body


def _message_records(
    batches: Sequence[Batch], order_batch: np.ndarray, order_row: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All Message records back to back in the given order; their offsets and sizes."""
    sizes_of = np.array([_MSG_HEADER + b.rows.shape[1] for b in batches], np.int64)
    sizes = sizes_of[order_batch]
    offsets = np.zeros(len(sizes), np.int64)
    if len(sizes):
        np.cumsum(sizes[:-1], out=offsets[1:])
    out = np.zeros(int(sizes.sum()), np.uint8)
    for i, b in enumerate(batches):
        sel = np.flatnonzero(order_batch == i)
        if len(sel) == 0:
            continue
        rows = order_row[sel]
        length = b.rows.shape[1]
        dtype = np.dtype(
            [
                ("op", "u1"),
                ("len", "<u8"),
                ("chan", "<u2"),
                ("seq", "<u4"),
                ("log", "<u8"),
                ("pub", "<u8"),
                ("data", "u1", (length,)),
            ]
        )
        rec = np.zeros(len(rows), dtype)
        rec["op"] = 0x05
        rec["len"] = 22 + length
        rec["chan"] = i + 1
        rec["seq"] = np.arange(len(rows)) % (1 << 32)
        rec["log"] = b.log_ns[rows]
        rec["pub"] = b.log_ns[rows]
        rec["data"] = b.rows[rows]
        size = dtype.itemsize
        window = np.ndarray((len(out) - size + 1,), f"V{size}", buffer=out, strides=(1,))
        window[offsets[sel]] = rec.view(f"V{size}")
    return out, offsets, sizes


def _schema_record(sid: int, msgtype: str, msgdef: str) -> bytes:
    return _record(0x03, _u16(sid) + _str(msgtype) + _str("ros2msg") + _str(msgdef))


def _channel_record(cid: int, sid: int, topic: str, qos: str) -> bytes:
    meta = _map([(_str("offered_qos_profiles"), _str(qos))])
    return _record(0x04, _u16(cid) + _u16(sid) + _str(topic) + _str("cdr") + meta)


class McapFile:
    """An MCAP file being written, record after record, keeping its CRCs.

    ``add_schema``/``add_channel`` write their records into the data section; ``chunk``
    writes one uncompressed Chunk (with the CRC32 of its records) and its MessageIndex
    records; ``finish`` writes the Metadata record, DataEnd with the data section CRC32, the
    summary and the Footer with the summary CRC32. Writes go to ``f`` as they come (the caller
    flushes).
    """

    def __init__(self, f: BinaryIO, library: str = "tire_model_ros") -> None:
        self.f = f
        self.crc = 0  # of the data section so far
        self.pos = 0
        self.schemas: list[bytes] = []
        self.channels: list[bytes] = []
        self.chunk_indexes: list[bytes] = []
        self.counts: dict[int, int] = {}
        self.span: tuple[int, int] | None = None  # first and last log time [ns]
        self._write(MAGIC)
        self._write(_record(0x01, _str("ros2") + _str(library)))

    def _write(self, data: bytes | memoryview) -> None:
        self.f.write(data)
        self.crc = zlib.crc32(data, self.crc)
        self.pos += len(data)

    def add_schema(self, sid: int, msgtype: str, msgdef: str) -> None:
        self.schemas.append(_schema_record(sid, msgtype, msgdef))
        self._write(self.schemas[-1])

    def add_channel(self, cid: int, sid: int, topic: str, qos: str) -> None:
        self.channels.append(_channel_record(cid, sid, topic, qos))
        self.counts[cid] = 0
        self._write(self.channels[-1])

    def chunk(
        self, records: memoryview | bytes, t0: int, t1: int, index: Sequence[tuple[int, Pairs]]
    ) -> None:
        """One Chunk of ``records`` (Message records back to back), log times ``t0``..``t1``
        [ns]; ``index``: per channel, its (log time, offset in ``records``) pairs."""
        size = len(records)
        body = _u64(t0) + _u64(t1) + _u64(size) + _u32(zlib.crc32(records)) + _str("")
        chunk_start = self.pos
        self._write(bytes([0x06]) + _u64(len(body) + 8 + size) + body + _u64(size))
        self._write(records)
        chunk_length = self.pos - chunk_start
        offsets = []
        for cid, pairs in index:
            offsets.append((cid, self.pos))
            self.counts[cid] += len(pairs)
            self._write(_record(0x07, _u16(cid) + _u32(pairs.nbytes) + pairs.tobytes()))
        self.chunk_indexes.append(
            _record(
                0x08,
                _u64(t0)
                + _u64(t1)
                + _u64(chunk_start)
                + _u64(chunk_length)
                + _map([(_u16(c), _u64(o)) for c, o in offsets])
                + _u64(self.pos - chunk_start - chunk_length)
                + _str("")
                + _u64(size)
                + _u64(size),
            )
        )
        self.span = (
            (t0, t1) if self.span is None else (min(self.span[0], t0), max(self.span[1], t1))
        )

    def finish(self, rosbag2_metadata: str = "") -> None:
        """Metadata, DataEnd, summary, Footer and the closing magic."""
        metadata_start = self.pos
        serialized = _map([(_str("serialized_metadata"), _str(rosbag2_metadata))])
        self._write(_record(0x0C, _str("rosbag2") + serialized))
        metadata_span = (metadata_start, self.pos - metadata_start)
        self._write(_record(0x0F, _u32(self.crc)))
        summary_start = self.pos
        summary = BytesIO()
        groups = []
        for op, data in (
            (0x03, b"".join(self.schemas)),
            (0x04, b"".join(self.channels)),
            (0x08, b"".join(self.chunk_indexes)),
            (
                0x0D,
                _record(0x0D, _u64(metadata_span[0]) + _u64(metadata_span[1]) + _str("rosbag2")),
            ),
            (0x0B, _record(0x0B, self._statistics())),
        ):
            if data:
                groups.append((op, summary_start + summary.tell(), len(data)))
                summary.write(data)
        offset_start = summary_start + summary.tell()
        for op, start, length in groups:
            summary.write(_record(0x0E, bytes([op]) + _u64(start) + _u64(length)))
        footer = bytes([0x02]) + _u64(20) + _u64(summary_start) + _u64(offset_start)
        summary_crc = zlib.crc32(footer, zlib.crc32(summary.getbuffer()))
        self.f.write(summary.getbuffer())
        self.f.write(footer + _u32(summary_crc) + MAGIC)

    def _statistics(self) -> bytes:
        t0, t1 = self.span or (0, 0)
        return (
            _u64(sum(self.counts.values()))
            + _u16(len(self.schemas))
            + _u32(len(self.channels))
            + _u32(0)
            + _u32(1)
            + _u32(len(self.chunk_indexes))
            + _u64(t0)
            + _u64(t1)
            + _map([(_u16(c), _u64(n)) for c, n in self.counts.items()])
        )


def write_mcap(
    path: Path,
    batches: Sequence[Batch],
    order: tuple[np.ndarray, np.ndarray],
    rosbag2_metadata: str = "",
    library: str = "tire_model_ros",
    chunk_bytes: int = CHUNK_BYTES,
) -> None:
    """Write ``batches`` to a new MCAP file; messages in ``order`` = (batch index, row index)
    arrays (time order: chunk time ranges and the index rely on it only for speed); chunks of
    about ``chunk_bytes`` of records."""
    order_batch, order_row = (np.asarray(o, np.int64) for o in order)
    records, offsets, sizes = _message_records(batches, order_batch, order_row)
    log_sorted = _ordered_log(batches, order_batch, order_row)
    # chunk boundaries at message boundaries, ~chunk_bytes each
    chunk_of = offsets // chunk_bytes
    bounds = np.flatnonzero(np.diff(chunk_of)) + 1
    starts = np.concatenate([[0], bounds]).astype(np.int64)
    ends = np.concatenate([bounds, [len(offsets)]]).astype(np.int64)
    with open(path, "xb") as f:
        out = McapFile(f, library)
        schema_ids: dict[str, int] = {}
        for i, b in enumerate(batches):
            if b.msgtype not in schema_ids:
                schema_ids[b.msgtype] = len(schema_ids) + 1
                out.add_schema(schema_ids[b.msgtype], b.msgtype, b.msgdef)
            out.add_channel(i + 1, schema_ids[b.msgtype], b.topic, b.qos)
        for a, z in zip(starts.tolist(), ends.tolist(), strict=True):
            if a == z:
                continue
            lo, hi = int(offsets[a]), int(offsets[z - 1] + sizes[z - 1])
            t = log_sorted[a:z]
            index = []
            for i in np.unique(order_batch[a:z]).tolist():
                sel = a + np.flatnonzero(order_batch[a:z] == i)
                pairs = np.empty((len(sel), 2), "<u8")
                pairs[:, 0] = log_sorted[sel]
                pairs[:, 1] = offsets[sel] - lo
                index.append((i + 1, pairs))
            out.chunk(records[lo:hi].data, int(t.min()), int(t.max()), index)
        out.finish(rosbag2_metadata)


def _ordered_log(
    batches: Sequence[Batch], order_batch: npt.NDArray[np.int64], order_row: npt.NDArray[np.int64]
) -> npt.NDArray[np.int64]:
    """Log times of the messages in write order."""
    out = np.empty(len(order_batch), np.int64)
    for i, b in enumerate(batches):
        sel = order_batch == i
        out[sel] = b.log_ns[order_row[sel]]
    return out
