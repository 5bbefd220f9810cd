"""Reading an MCAP file record by record: unindexed files, unclosed files, and salvage.

``read_mcap`` is the one entry for an MCAP storage file: the indexed path of
:mod:`.mcap_index` when the file is closed and indexed, else this linear scan, which walks
the data section from the magic: Schema and Channel records, Chunks (each one's CRC checked,
then its records walked), bare Message records (an unchunked file), up to DataEnd (its data
section CRC checked) or the Footer.

A file that ends without its Footer (a recorder killed before closing it) is refused, naming
where it ends; with ``salvage`` its complete chunks are read. With ``salvage`` a damaged chunk
is skipped (the message indexes after it say how many messages of which topics it held), and
after an unreadable record the scan resumes at the next chunk whose header and CRC hold.
Messages come only from chunks whose CRC holds (or that have none) and from bare records.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tire_model_ros.recording import mcap_check
from tire_model_ros.recording.errors import Damage, DamagedBagError
from tire_model_ros.recording.mcap_check import MAGIC
from tire_model_ros.recording.mcap_index import (
    Declared,
    McapContent,
    Pieces,
    Rescan,
    assemble,
    read_indexed,
)

_SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _MESSAGE_INDEX = 0x03, 0x04, 0x05, 0x06, 0x07
_FOOTER, _DATA_END = 0x02, 0x0F
_COMPRESSIONS = (b"", b"zstd", b"lz4")
#: (channel id, data start in the joined buffer, data length, log time [ns]) per message.
Found = list[tuple[int, int, int, int]]


def read_mcap(file: Path, select: Callable[[str], bool], salvage: bool = False) -> McapContent:
    """The selected topics of one MCAP file: indexed when it can be, else scanned.

    Raises
    ------
    DamagedBagError
        (not ``salvage``) a damaged or unclosed file, naming it, the byte offset and topics.
    ValueError
        a file that is not an MCAP file at all.
    """
    filebuf = np.fromfile(file, np.uint8)
    got = read_indexed(file, filebuf, select, salvage)
    if isinstance(got, McapContent):
        return got
    raw = filebuf.tobytes()  # the scan slices and searches bytes
    scan = _Scan(file, raw, salvage, got.declared if isinstance(got, Rescan) else None)
    if isinstance(got, Rescan):
        scan.damages.append(got.damage)
    scan.run(closed_file=mcap_check.find_ends(filebuf) is not None)
    return scan.content(select)


def _string(buf: bytes, p: int, end: int) -> tuple[str, int]:
    """A u32-length-prefixed UTF-8 string at ``p`` and the offset after it."""
    if p + 4 > end:
        raise ValueError("string length runs past its record")
    (k,) = struct.unpack_from("<I", buf, p)
    if p + 4 + k > end:
        raise ValueError("string runs past its record")
    return buf[p + 4 : p + 4 + k].decode("utf-8"), p + 4 + k


@dataclass
class _Pending:
    """A skipped chunk; the MessageIndex records after it tell what it held."""

    offset: int
    reason: str
    lost: dict[int, int] = field(default_factory=dict)
    indexed: bool = False


class _Scan:
    """State of one linear scan (see the module docstring)."""

    def __init__(self, file: Path, raw: bytes, salvage: bool, declared: Declared | None) -> None:
        self.file, self.raw, self.salvage = file, raw, salvage
        self.fixed = declared is not None  # a CRC-checked summary declares schemas and channels
        self.schemas = dict(declared.schemas) if declared else {}
        self.channels = dict(declared.channels) if declared else {}
        self.found: Found = []
        self.segments: list[bytes] = []
        self.base = 0
        self.damages: list[Damage] = []
        self.chunks = 0
        self.pending: _Pending | None = None

    # ------------------------------------------------------------------ walking

    def run(self, closed_file: bool) -> None:
        raw, n = self.raw, len(self.raw)
        if raw[: len(MAGIC)] != MAGIC:
            if not raw.startswith(MAGIC[:5]):
                raise ValueError("not an MCAP file (no MCAP magic at its start)")
            self._damage(Damage(self.file, "record", "damaged MCAP magic", 0))
        pos, closed = len(MAGIC), False
        while pos < n:
            op, length = struct.unpack_from("<BQ", raw, pos) if pos + 9 <= n else (0, 0)
            end = pos + 9 + length if pos + 9 <= n and pos + 9 + length <= n else -1
            if end < 0 and not closed_file:
                break  # the file ends inside this record: it was not closed
            if end >= 0 and op in (_DATA_END, _FOOTER):
                if op == _DATA_END:
                    self._data_end(pos, length)
                closed = True
                break
            if end < 0 or op == 0 or 0x10 <= op < 0x80:
                resume = self._unreadable(pos, op, length)
                if resume is None:
                    closed = True  # nothing sound follows; said by _unreadable
                    break
                pos = resume
                continue
            self._record(op, pos, end)
            pos = end
        self._finish_pending()
        if not closed:
            where = "inside a record" if pos < n else "after a complete record"
            self._damage(
                Damage(
                    self.file,
                    "end of file",
                    f"truncated: the file ends {where}, without its footer (not closed: a "
                    f"recorder killed?); {self.chunks} complete chunk(s) before it",
                    pos,
                )
            )
        self._check_undeclared()

    def _record(self, op: int, pos: int, end: int) -> None:
        if op == _MESSAGE_INDEX and self.pending is not None:
            self._index_of_skipped(pos, end)
            return
        self._finish_pending()
        if op == _CHUNK:
            self._chunk(pos, end)
        elif op == _MESSAGE:
            found: Found = []
            record = self.raw[pos:end]
            reason = self._records(record, self.base, found)
            if reason is not None:
                self._damage(Damage(self.file, "record", reason, pos))
                return
            self._commit(record, found)
        elif op in (_SCHEMA, _CHANNEL):
            reason = self._declare(op, self.raw, pos + 9, end)
            if reason is not None:
                self._damage(Damage(self.file, "record", reason, pos))

    def _chunk(self, pos: int, end: int) -> None:
        from rosbags.rosbag2.storage_mcap import decompress

        raw = self.raw
        try:
            _t0, _t1, size, stored, clen = struct.unpack_from("<QQQII", raw, pos + 9)
            cstart = pos + 9 + 32
            compression = raw[cstart : cstart + clen].decode()
            (rlen,) = struct.unpack_from("<Q", raw, cstart + clen)
            if cstart + clen + 8 + rlen != end:
                raise ValueError("its length disagrees with its records' length")
            data = raw[cstart + clen + 8 : end]
            records = decompress(data, compression, size, 0) if compression else data
            if len(records) != size:
                raise ValueError("its uncompressed size disagrees with its records")
            reason = mcap_check.chunk_crc_reason(stored, records)
        except Exception as exc:  # struct, decode and decompression errors of a damaged chunk
            reason = f"unreadable ({type(exc).__name__}: {exc})"
        found: Found = []
        if reason is None:
            reason = self._records(records, self.base, found)
        if reason is not None:
            self.pending = _Pending(pos, reason)
            return
        self._commit(records, found)
        self.chunks += 1

    def _commit(self, segment: bytes, found: Found) -> None:
        self.segments.append(segment)
        self.base += len(segment)
        self.found.extend(found)

    def _records(self, rec: bytes, base: int, out: Found) -> str | None:
        """Walk the records of ``rec`` (a chunk's, or one bare record); messages to ``out``
        with starts offset by ``base``. Returns why they do not parse, or None."""
        p, m = 0, len(rec)
        while p < m:
            if p + 9 > m:
                return "a record is cut short inside its chunk"
            op, length = struct.unpack_from("<BQ", rec, p)
            body, end = p + 9, p + 9 + length
            if end > m:
                return "a record runs past the end of its chunk"
            if op == _MESSAGE:
                if length < 22:
                    return "a message record is too short"
                cid, _seq, log_ns = struct.unpack_from("<HIQ", rec, body)
                if log_ns >= 1 << 63:
                    return "a message's log time is out of range"
                out.append((cid, base + body + 22, length - 22, log_ns))
            elif op in (_SCHEMA, _CHANNEL):
                reason = self._declare(op, rec, body, end)
                if reason is not None:
                    return reason
            p = end
        return None

    def _declare(self, op: int, buf: bytes, p: int, end: int) -> str | None:
        """Parse a Schema or Channel record's body; None when it parses (or is not needed)."""
        try:
            if op == _SCHEMA:
                (sid,) = struct.unpack_from("<H", buf, p)
                name, q = _string(buf, p + 2, end)
                _encoding, q = _string(buf, q, end)
                (k,) = struct.unpack_from("<I", buf, q)
                text = buf[q + 4 : q + 4 + k].decode("utf-8", "replace")
                if not self.fixed:
                    self.schemas[sid] = (name, text)
            else:
                cid, sid = struct.unpack_from("<HH", buf, p)
                topic, q = _string(buf, p + 4, end)
                _string(buf, q, end)
                if not self.fixed:
                    self.channels[cid] = (topic, sid)
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            return f"unreadable {'schema' if op == _SCHEMA else 'channel'} record ({exc})"
        return None

    def _data_end(self, pos: int, length: int) -> None:
        """The data section CRC, when written and no damage found so far explains a mismatch."""
        self._finish_pending()
        if length < 4 or self.damages:
            return
        (stored,) = struct.unpack_from("<I", self.raw, pos + 9)
        if stored and mcap_check.crc(self.raw[:pos]) != stored:
            ends = mcap_check.Ends(0, 0, 0, 0, pos, stored)
            self._damage(mcap_check.data_section_damage(self.file, ends))

    def _unreadable(self, pos: int, op: int, length: int) -> int | None:
        """Note an unreadable record; where to resume (the next sound chunk), or None."""
        self._finish_pending()
        reason = f"unreadable record (opcode {op:#04x}, length {length})"
        self._damage(Damage(self.file, "record", reason, pos))
        resume = self._next_chunk(pos + 1)
        if resume is None:
            self._damage(
                Damage(self.file, "end of file", "no sound chunk after the unreadable record", pos)
            )
        return resume

    def _next_chunk(self, start: int) -> int | None:
        q = self.raw.find(b"\x06", start)
        while q >= 0:
            if self._chunk_fits(q):
                return q
            q = self.raw.find(b"\x06", q + 1)
        return None

    def _chunk_fits(self, q: int) -> bool:
        """A Chunk record at ``q`` whose lengths agree and whose CRC (if any) holds."""
        raw, n = self.raw, len(self.raw)
        if q + 9 + 40 > n:
            return False
        (length,) = struct.unpack_from("<Q", raw, q + 1)
        end = q + 9 + length
        _t0, _t1, size, stored, clen = struct.unpack_from("<QQQII", raw, q + 9)
        if end > n or clen > 4 or q + 41 + clen + 8 > end:
            return False
        compression = raw[q + 41 : q + 41 + clen]
        (rlen,) = struct.unpack_from("<Q", raw, q + 41 + clen)
        if compression not in _COMPRESSIONS or q + 49 + clen + rlen != end:
            return False
        records = raw[q + 49 + clen : end]
        if compression:
            return True  # decompressed and checked when read
        return rlen == size and mcap_check.chunk_crc_reason(stored, records) is None

    # ------------------------------------------------------------------ damage

    def _index_of_skipped(self, pos: int, end: int) -> None:
        assert self.pending is not None
        if end - pos < 15:
            return
        cid, nbytes = struct.unpack_from("<HI", self.raw, pos + 9)
        self.pending.lost[cid] = self.pending.lost.get(cid, 0) + nbytes // 16
        self.pending.indexed = True

    def _finish_pending(self) -> None:
        """Name the skipped chunk, with the topics its message indexes gave."""
        pending, self.pending = self.pending, None
        if pending is None:
            return
        declared = Declared(self.schemas, self.channels)
        lost: dict[str, int] | None = None
        if pending.indexed:
            lost = {}
            for cid, k in pending.lost.items():
                lost[declared.topic(cid)] = lost.get(declared.topic(cid), 0) + k
        topics = tuple(sorted(lost)) if lost else ()
        self._damage(Damage(self.file, "chunk", pending.reason, pending.offset, topics, lost))

    def _damage(self, damage: Damage) -> None:
        self.damages.append(damage)
        if not self.salvage:
            raise DamagedBagError(self.damages)

    def _check_undeclared(self) -> None:
        undeclared: dict[int, int] = {}
        for cid, *_ in self.found:
            if cid not in self.channels:
                undeclared[cid] = undeclared.get(cid, 0) + 1
        for cid, k in sorted(undeclared.items()):
            self._damage(
                Damage(
                    self.file,
                    "record",
                    f"{k} message(s) of channel {cid}, which no Channel record declares: skipped",
                )
            )
        if undeclared:
            self.found = [f for f in self.found if f[0] not in undeclared]

    # ------------------------------------------------------------------ result

    def content(self, select: Callable[[str], bool]) -> McapContent:
        declared = Declared(self.schemas, self.channels)
        counts = dict.fromkeys(self.channels, 0)
        pieces: Pieces = {}
        if self.found:
            columns = (np.asarray(c, np.int64) for c in zip(*self.found, strict=True))
            cid, starts, lens, log_ns = columns
            for c in self.channels:
                sel = cid == c
                counts[c] = int(sel.sum())
                if select(self.channels[c][0]):
                    pieces[c] = [(starts[sel], lens[sel], log_ns[sel])]
        buffer = np.frombuffer(b"".join(self.segments), np.uint8)
        return assemble(declared, pieces, counts, buffer, None, self.damages)
