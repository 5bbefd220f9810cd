"""The CRCs of an MCAP file (https://mcap.dev/spec): where they are and whether they hold.

An MCAP file carries up to three kinds of CRC32 (zlib's, ``zlib.crc32``):

- each Chunk record: the CRC of its *uncompressed* records (``uncompressed_crc``);
- the DataEnd record: the CRC of every byte from the start of the file (magic included) up to
  the DataEnd record (``data_section_crc``);
- the Footer: the CRC of the summary section and of the Footer's own fields before the CRC
  (``summary_crc``).

A CRC of 0 means "not written" (rosbags writes no chunk CRCs; rosbag2 no data section CRC).
These helpers locate the Footer and DataEnd records from the end of the file and compare the
CRCs; the readers decide what to do with a mismatch.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.errors import Damage

MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER = 0x02
OP_CHUNK = 0x06
OP_DATA_END = 0x0F
FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
DATA_END_BYTES = 1 + 8 + 4
#: Chunk record bytes before its compression string: opcode, length, start/end time,
#: uncompressed size, uncompressed CRC, compression string length.
CHUNK_HEAD = 1 + 8 + 8 + 8 + 8 + 4 + 4
Bytes = npt.NDArray[np.uint8]


@dataclass(frozen=True)
class Ends:
    """Where a closed MCAP file's Footer and DataEnd records are, and their CRC fields."""

    footer: int  # byte offset of the Footer record
    summary_start: int  # 0: the file has no summary section
    summary_offset_start: int
    summary_crc: int  # 0: not written
    data_end: int | None  # byte offset of the DataEnd record; None: not where expected
    data_crc: int  # 0: not written (or no DataEnd found)


def crc(buf: Bytes | bytes, crc0: int = 0) -> int:
    """zlib's CRC32 of ``buf`` continued from ``crc0``."""
    return zlib.crc32(buf if isinstance(buf, bytes) else buf.data, crc0) & 0xFFFFFFFF


def find_ends(filebuf: Bytes) -> Ends | None:
    """The Footer and DataEnd of a file that ends with a Footer and the magic, else None."""
    n = len(filebuf)
    footer = n - len(MAGIC) - FOOTER_BYTES
    if footer < len(MAGIC) or bytes(filebuf[n - len(MAGIC) :]) != MAGIC:
        return None
    op, length, summary_start, offset_start, summary_crc = struct.unpack_from(
        "<BQQQI", filebuf.data, footer
    )
    if op != OP_FOOTER or length != FOOTER_BYTES - 9 or summary_start >= footer:
        return None
    at = (summary_start or footer) - DATA_END_BYTES
    data_end, data_crc = None, 0
    if at >= len(MAGIC):
        op, length, value = struct.unpack_from("<BQI", filebuf.data, at)
        if op == OP_DATA_END and length == 4:
            data_end, data_crc = at, value
    return Ends(footer, summary_start, offset_start, summary_crc, data_end, data_crc)


def summary_damage(file: Path, filebuf: Bytes, ends: Ends) -> Damage | None:
    """A Damage when the Footer's summary CRC is written and does not match."""
    if ends.summary_crc == 0:
        return None
    start = ends.summary_start or ends.footer
    got = crc(filebuf[start : ends.footer + FOOTER_BYTES - 4])
    if got == ends.summary_crc:
        return None
    reason = f"CRC mismatch (stored {ends.summary_crc:#010x}, computed {got:#010x})"
    return Damage(file, "summary", reason, start)


def data_section_ok(filebuf: Bytes, ends: Ends) -> bool | None:
    """Whether the data section CRC matches; None when the file has none."""
    if ends.data_end is None or ends.data_crc == 0:
        return None
    return crc(filebuf[: ends.data_end]) == ends.data_crc


def data_section_damage(file: Path, ends: Ends) -> Damage:
    """The data section's CRC fails while every chunk's holds: the damage is between chunks."""
    return Damage(
        file,
        "data section",
        "CRC mismatch outside the chunks' records (a chunk header, message index, schema, "
        "channel or metadata record)",
        ends.data_end,
    )


def chunk_crc_reason(stored: int, records: Bytes | bytes) -> str | None:
    """Why a chunk's records do not match its stored CRC, or None (match, or no CRC)."""
    if stored == 0:
        return None
    got = crc(records)
    if got == stored:
        return None
    return f"CRC mismatch (stored {stored:#010x}, computed {got:#010x})"
