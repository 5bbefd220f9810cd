"""Per-message CDR fast path for the node's topics (no ROS import).

Every topic of the node is ``std_msgs/Header`` followed by float64 fields; the node reads a
few of those doubles and writes a WrenchStamped with the slip's header. Deserialising a
message into a Python object costs 40-60 us here, this costs ~2 us, so the node subscribes
with ``raw=True`` and uses these functions (layout in ``tire_model_ros.recording.cdr``)::

    0   encapsulation  00 01 00 00 (CDR_LE)
    4   stamp.sec int32, 8 stamp.nanosec uint32
    12  frame_id: uint32 length L (with the NUL), then L bytes
    4 + ceil8(12 + L)  float64 fields (aligned to 8 relative to offset 4)

Anything else (big-endian CDR, truncated data) returns None and the caller falls back to
rclpy's deserialiser, so no message is misread.
"""

from __future__ import annotations

import struct

_LE = b"\x00\x01"
_D6 = struct.Struct("<6d")
_ZEROS = bytes(8)


def header_end(data: bytes) -> int | None:
    """Offset just after the header (end of frame_id), or None if not a CDR_LE header."""
    if len(data) < 16 or data[:2] != _LE:
        return None
    end = 16 + int.from_bytes(data[12:16], "little")
    return end if end <= len(data) else None


def _payload(end: int) -> int:
    """Offset of the first float64 after a header ending at ``end``."""
    return 4 + ((end - 4 + 7) & ~7)


def read_double(data: bytes, index: int) -> float | None:
    """The ``index``-th float64 after the header, or None when the layout does not fit."""
    end = header_end(data)
    if end is None:
        return None
    off = _payload(end) + 8 * index
    if off + 8 > len(data):
        return None
    value: float = struct.unpack_from("<d", data, off)[0]
    return value


def read_vector(data: bytes) -> tuple[int, float, float, float] | None:
    """(header end, x, y, z) of a Vector3Stamped, or None when the layout does not fit."""
    end = header_end(data)
    if end is None:
        return None
    off = _payload(end)
    if off + 24 > len(data):
        return None
    x, y, z = struct.unpack_from("<3d", data, off)
    return end, x, y, z


def read_stamp_ns(data: bytes) -> int:
    """header.stamp [ns] of a message whose header ``read_vector``/``read_double`` accepted."""
    sec, nanosec = struct.unpack_from("<iI", data, 4)
    return int(sec) * 1_000_000_000 + int(nanosec)


def wrench_like(data: bytes, end: int, values: tuple[float, ...]) -> bytes:
    """A WrenchStamped with the header of ``data`` (bytes up to ``end``) and six values."""
    pad = _payload(end) - end
    return b"".join((data[:end], _ZEROS[:pad], _D6.pack(*values)))
