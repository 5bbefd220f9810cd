"""Streaming MCAP writer: messages one at a time, complete chunks on disk at least every
``flush_s`` seconds.

A chunk is closed and written (with its CRC and message indexes, then flushed to the operating
system) when its records reach ``chunk_bytes`` or when it has been open ``flush_s`` seconds of
wall time; ``flush_due()`` closes an old chunk when no message comes to do it. A process
killed with SIGKILL therefore leaves a file whose complete chunks hold everything but its last
``flush_s`` seconds: ``read_raw(..., salvage=True)`` reads them. The file is finished (summary,
footer) by ``close``.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np

from tire_model_ros.recording.mcap_write import CHUNK_BYTES, McapFile

#: opcode u8, record length u64, channel u16, sequence u32, log time u64, publish time u64
_MESSAGE = struct.Struct("<BQHIQQ")
#: Wall seconds a chunk stays open at most: a kill loses at most this (plus one spin).
FLUSH_S = 0.5


class McapStreamWriter:
    """Writes messages into a new MCAP file chunk by chunk (see the module docstring)."""

    def __init__(
        self,
        path: Path,
        *,
        chunk_bytes: int = CHUNK_BYTES,
        flush_s: float = FLUSH_S,
        library: str = "tire_model_ros",
    ) -> None:
        self._fh = open(path, "xb")  # noqa: SIM115 (closed by close() / abort())
        self.file = McapFile(self._fh, library)
        self.chunk_bytes, self.flush_s = chunk_bytes, flush_s
        self._schemas: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self._chunk = bytearray()
        self._index: dict[int, list[int]] = {}  # channel -> log, offset, log, offset ...
        self._span: tuple[int, int] | None = None
        self._opened: float | None = None  # monotonic time of the open chunk's first message
        self._fh.flush()

    def add_channel(self, topic: str, msgtype: str, msgdef: str, qos: str = "[]") -> int:
        """Declare a topic; returns its channel id (Schema and Channel records written now)."""
        if msgtype not in self._schemas:
            self._schemas[msgtype] = len(self._schemas) + 1
            self.file.add_schema(self._schemas[msgtype], msgtype, msgdef)
        cid = len(self._seq) + 1
        self.file.add_channel(cid, self._schemas[msgtype], topic, qos)
        self._seq[cid] = 0
        self._fh.flush()
        return cid

    def write(self, cid: int, log_ns: int, data: bytes | memoryview) -> None:
        """One message of channel ``cid`` with log time ``log_ns`` [ns]."""
        offset = len(self._chunk)
        self._chunk += _MESSAGE.pack(0x05, 22 + len(data), cid, self._seq[cid], log_ns, log_ns)
        self._chunk += data
        self._seq[cid] = (self._seq[cid] + 1) & 0xFFFFFFFF
        self._index.setdefault(cid, []).extend((log_ns, offset))
        first, last = self._span or (log_ns, log_ns)
        self._span = (min(first, log_ns), max(last, log_ns))
        if self._opened is None:
            self._opened = time.monotonic()
        if len(self._chunk) >= self.chunk_bytes:
            self.flush()
        else:
            self.flush_due()

    def flush_due(self) -> bool:
        """Write the open chunk if it is ``flush_s`` old; True if it did."""
        if self._opened is None or time.monotonic() - self._opened < self.flush_s:
            return False
        self.flush()
        return True

    def flush(self) -> None:
        """Write the open chunk (if any) and hand it to the operating system."""
        if self._span is not None:
            index = [
                (cid, np.asarray(v, np.uint64).reshape(-1, 2)) for cid, v in self._index.items()
            ]
            self.file.chunk(memoryview(self._chunk), *self._span, index)
            self._chunk = bytearray()
            self._index = {}
            self._span = None
            self._opened = None
        self._fh.flush()

    def close(self, rosbag2_metadata: str = "") -> None:
        """Write the last chunk, the summary and the footer; close the file."""
        try:
            self.flush()
            self.file.finish(rosbag2_metadata)
        finally:
            self._fh.close()

    def abort(self) -> None:
        """Close the file as it is (its complete chunks stay readable by salvage)."""
        self._fh.close()
