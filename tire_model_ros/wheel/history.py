"""A short history of one input of the node, looked up by header stamp (no ROS import).

Each slip message is answered with every other input as the offline tool aligns a recording
(INTERFACE.md, "Time and matching in the node"): the latest value whose header stamp is at or
before the slip's stamp, found by the one rule of :func:`tire_model_ros.recording.align.
latest_at_or_before`. An input is stale when that value's stamp is more than its timeout older
than the slip's stamp: stamp time only, so a paused or fast-forwarded simulator and a replayed
bag give the answers the offline tool gives.

The history keeps the last :data:`CAPACITY` values in stamp order (messages that arrive out of
order are put in their place; of equal stamps the later arrival wins, as the later message of
a bag). 8192 values are 8 s of a 1 kHz input: the slip topic may fall behind the inputs (a
reliable topic that loses a sample delivers nothing after it until the writer's next
heartbeat repairs it, every 3 s in Fast DDS by default); ``make demo``'s replay beside two
CPU hogs had inputs up to 457 messages ahead of the slips, which 256 values did not cover. A
slip stamped further back than the history reaches finds no value old enough (state
``"ahead"``) and takes the nominal one. Appending is a store (the window is moved back once
per ``capacity`` appends); only a message out of order moves values.

One deliberate difference from the offline reader: that one holds an optional channel's first
value backwards over the samples before it (it sees the whole recording); the node cannot see
the future, so a slip before an input's first message has no value for it (``"ahead"``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from tire_model_ros.recording.align import latest_at_or_before

CAPACITY = 8192
#: States of a lookup: a value at or before the stamp and fresh; nothing ever received; the
#: value found is older than the timeout; every value is stamped after the slip.
STATES = ("ok", "never", "stale", "ahead")


class StampedHistory:
    """The last :data:`CAPACITY` values of one input with their header stamps [ns]."""

    def __init__(self, capacity: int = CAPACITY) -> None:
        self.capacity = capacity
        # a window [lo, hi) of a buffer twice the capacity: appending is a store, and the window
        # moves back to the front once per ``capacity`` appends
        self._stamps: npt.NDArray[np.int64] = np.zeros(2 * capacity, np.int64)
        self._values: npt.NDArray[np.float64] = np.zeros(2 * capacity)
        self._lo = 0
        self._hi = 0

    def __len__(self) -> int:
        return self._hi - self._lo

    def put(self, stamp_ns: int, value: float) -> None:
        """Add a value; out-of-order stamps go to their place, the oldest falls out."""
        if self._hi == len(self._stamps):
            self._compact()
        lo, hi = self._lo, self._hi
        if hi == lo or stamp_ns >= self._stamps[hi - 1]:
            self._stamps[hi] = stamp_ns
            self._values[hi] = value
        else:  # out of order: after every value stamped at or before it
            at = lo + int(latest_at_or_before(self._stamps[lo:hi], np.int64(stamp_ns))) + 1
            self._stamps[at + 1 : hi + 1] = self._stamps[at:hi].copy()
            self._values[at + 1 : hi + 1] = self._values[at:hi].copy()
            self._stamps[at] = stamp_ns
            self._values[at] = value
        self._hi = hi + 1
        self._lo = max(self._lo, self._hi - self.capacity)

    def _compact(self) -> None:
        n = self._hi - self._lo
        self._stamps[:n] = self._stamps[self._lo : self._hi].copy()
        self._values[:n] = self._values[self._lo : self._hi].copy()
        self._lo, self._hi = 0, n

    def at(self, t_ns: int, timeout_ns: int) -> tuple[float | None, str, int]:
        """(value, state, its stamp [ns]) for a slip stamped ``t_ns``; see :data:`STATES`.

        ``timeout_ns`` 0 means never stale. The value is None unless the state is "ok".
        """
        lo, hi = self._lo, self._hi
        if hi == lo:
            return None, "never", 0
        i = int(latest_at_or_before(self._stamps[lo:hi], np.int64(t_ns)))
        if i < 0:
            return None, "ahead", int(self._stamps[lo])
        stamp = int(self._stamps[lo + i])
        if timeout_ns > 0 and t_ns - stamp > timeout_ns:
            return None, "stale", stamp
        return float(self._values[lo + i]), "ok", stamp

    def latest(self) -> tuple[float, int] | None:
        """(value, stamp [ns]) of the newest-stamped value, None when empty."""
        if self._hi == self._lo:
            return None
        return float(self._values[self._hi - 1]), int(self._stamps[self._hi - 1])
