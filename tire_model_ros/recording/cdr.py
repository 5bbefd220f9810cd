"""Vectorised CDR encode/decode of the fixed-layout message types of INTERFACE.md.

Every recorded type is ``std_msgs/Header`` followed by a fixed number of float64 fields, so
the CDR bytes of a message are (little-endian CDR, offsets from the start of the buffer)::

    0   encapsulation  00 01 00 00   (CDR_LE; 00 00 = CDR_BE)
    4   stamp.sec      int32
    8   stamp.nanosec  uint32
    12  frame_id       uint32 length L (including the NUL), then L bytes
    4 + ceil8(12 + L)  float64 * k   (CDR aligns 8-byte primitives relative to offset 4)

Only ``frame_id`` makes the layout variable, so the whole batch of messages of one topic is
decoded with fancy indexing over one joined byte buffer: no Python loop per message.
Messages that do not fit this layout (big-endian CDR, truncated) are decoded with rosbags'
deserialiser, the reference implementation (see ``decode_reference``).

No ROS import here.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from tire_model_ros.vocabulary import (
    FLUID_PRESSURE,
    NS_PER_S,
    TEMPERATURE,
    TWIST_STAMPED,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)

#: float64 fields after the header, in CDR order, for each supported type.
LAYOUTS: dict[str, tuple[str, ...]] = {
    VECTOR3_STAMPED: ("vector.x", "vector.y", "vector.z"),
    WRENCH_STAMPED: (
        "wrench.force.x",
        "wrench.force.y",
        "wrench.force.z",
        "wrench.torque.x",
        "wrench.torque.y",
        "wrench.torque.z",
    ),
    FLUID_PRESSURE: ("fluid_pressure", "variance"),
    TEMPERATURE: ("temperature", "variance"),
    TWIST_STAMPED: (
        "twist.linear.x",
        "twist.linear.y",
        "twist.linear.z",
        "twist.angular.x",
        "twist.angular.y",
        "twist.angular.z",
    ),
}


class CdrError(ValueError):
    """A message whose bytes cannot be decoded (index of the first bad message in ``index``)."""

    def __init__(self, message: str, index: int) -> None:
        super().__init__(message)
        self.index = index


if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Jazzy typestore of rosbags (built once; it takes ~0.1 s)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _gather_words(
    buf: npt.NDArray[np.uint8], offsets: npt.NDArray[np.int64], count: int, dtype: str
) -> npt.NDArray[Any]:
    """``count`` consecutive words of ``dtype`` at each byte offset of ``buf``, (n, count).

    Gathers from a view of ``buf`` with a 1-byte stride (word i starts at byte i, unaligned
    reads allowed), so each word is one index operation instead of one per byte.
    """
    size = np.dtype(dtype).itemsize
    buf = np.ascontiguousarray(buf, np.uint8)
    if len(buf) < size:
        return np.empty((len(offsets), count), dtype)
    window = np.ndarray((len(buf) - size + 1,), dtype, buffer=buf, strides=(1,))
    index = np.asarray(offsets, np.int64)[:, None] + size * np.arange(count, dtype=np.int64)
    words: npt.NDArray[Any] = window[index]
    return words


def join(raw: Sequence[bytes | memoryview]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One buffer holding every message, and each message's start and length in it."""
    n = len(raw)
    lens = np.fromiter(map(len, raw), np.int64, n)
    starts = np.zeros(n, np.int64)
    if n:
        np.cumsum(lens[:-1], out=starts[1:])
    return np.frombuffer(b"".join(raw), np.uint8), starts, lens


def decode(
    msgtype: str, buf: np.ndarray, starts: np.ndarray, lens: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Header stamps [ns] and float64 fields of a batch of CDR messages of one type.

    Parameters
    ----------
    buf : uint8 buffer; message i is ``buf[starts[i] : starts[i] + lens[i]]``.

    Returns
    -------
    stamp_ns : ndarray of int64, shape (n,)
    values : ndarray of float64, shape (n, k), columns as ``LAYOUTS[msgtype]``

    Raises
    ------
    KeyError
        ``msgtype`` has no fixed layout here.
    CdrError
        A message is neither the fixed little-endian layout nor decodable by rosbags.
    """
    k = len(LAYOUTS[msgtype])
    n = len(starts)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros((0, k))
    starts = np.asarray(starts, np.int64)
    lens = np.asarray(lens, np.int64)
    ok = (lens >= 16) & (starts + lens <= len(buf))
    # Short messages are masked out below; read their header from offset 0 meanwhile.
    safe = np.where(ok, starts, 0)
    if len(buf) < 16:
        buf = np.concatenate([buf, np.zeros(16, np.uint8)])
    enc = _gather_words(buf, safe, 2, "u1")
    ok &= (enc[:, 0] == 0) & (enc[:, 1] == 1)
    words = _gather_words(buf, safe + 4, 3, "<u4")
    sec = words[:, 0].view("<i4").astype(np.int64)
    nsec = words[:, 1].astype(np.int64)
    slen = words[:, 2].astype(np.int64)
    data_off = 4 + ((12 + slen + 7) // 8) * 8
    ok &= (slen >= 1) & (data_off + 8 * k <= lens) & (nsec < NS_PER_S)
    values = np.empty((n, k))
    good = np.flatnonzero(ok)
    if len(good) == n:
        values[:] = _gather_words(buf, starts + data_off, k, "<f8")
    elif len(good):
        values[good] = _gather_words(buf, starts[good] + data_off[good], k, "<f8")
    stamp_ns = sec * NS_PER_S + nsec
    for i in np.flatnonzero(~ok):  # rare: big-endian CDR or a damaged message
        data = buf[starts[i] : starts[i] + lens[i]].tobytes()
        try:
            stamp_ns[i], values[i] = decode_reference(msgtype, data)
        except Exception as exc:  # rosbags raises assorted errors on garbage bytes
            raise CdrError(
                f"message #{i} ({lens[i]} bytes) cannot be decoded: {exc}", int(i)
            ) from None
    return stamp_ns, values


def _field(msg: object, dotted: str) -> float:
    for part in dotted.split("."):
        msg = getattr(msg, part)
    return float(msg)  # type: ignore[arg-type]


def decode_reference(msgtype: str, data: bytes | memoryview) -> tuple[int, np.ndarray]:
    """One message decoded with rosbags' deserialiser: (stamp [ns], fields). The reference."""
    msg: Any = typestore().deserialize_cdr(bytes(data), msgtype)  # a generated dataclass
    stamp = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
    return stamp, np.array([_field(msg, f) for f in LAYOUTS[msgtype]])


def encode_array(
    msgtype: str, stamp_ns: np.ndarray, values: np.ndarray, frame_id: str = ""
) -> np.ndarray:
    """CDR_LE bytes of one message per row, as an (n, size) uint8 array (same bytes as
    rosbags' ``serialize_cdr``)."""
    k = len(LAYOUTS[msgtype])
    stamp_ns = np.asarray(stamp_ns, np.int64)
    values = np.asarray(values, np.float64).reshape(len(stamp_ns), k)
    name = frame_id.encode() + b"\0"
    pad = ((12 + len(name) + 7) // 8) * 8 - 12  # frame_id bytes + alignment padding
    dtype = np.dtype(
        [
            ("enc", "u1", 4),
            ("sec", "<i4"),
            ("nsec", "<u4"),
            ("slen", "<u4"),
            ("name", f"S{pad}"),
            ("vals", "<f8", k),
        ]
    )
    sec = stamp_ns // NS_PER_S
    if len(sec) and (sec.min() < -(2**31) or sec.max() >= 2**31):
        raise ValueError("a stamp is outside the int32 seconds of builtin_interfaces/Time")
    rec = np.zeros(len(stamp_ns), dtype)
    rec["enc"] = (0, 1, 0, 0)
    rec["sec"] = sec
    rec["nsec"] = stamp_ns % NS_PER_S
    rec["slen"] = len(name)
    rec["name"] = name
    rec["vals"] = values
    return rec.view(np.uint8).reshape(len(rec), dtype.itemsize)


def encode(
    msgtype: str, stamp_ns: np.ndarray, values: np.ndarray, frame_id: str = ""
) -> list[memoryview]:
    """CDR_LE bytes of one message per row, one memoryview each (see ``encode_array``)."""
    rows = encode_array(msgtype, stamp_ns, values, frame_id)
    mv = memoryview(np.ascontiguousarray(rows).tobytes())
    size = rows.shape[1]
    return [mv[i * size : (i + 1) * size] for i in range(len(rows))]


def header_stamps(buf: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Header stamps [ns] of CDR_LE messages that start with a ``std_msgs/Header``."""
    if len(starts) == 0:
        return np.zeros(0, np.int64)
    words = _gather_words(buf, np.asarray(starts, np.int64) + 4, 2, "<u4")
    return words[:, 0].view("<i4").astype(np.int64) * NS_PER_S + words[:, 1].astype(np.int64)
