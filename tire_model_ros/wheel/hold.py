"""Slip messages held until the other inputs' stamps have caught up (no ROS import).

A slip is answered with each input's latest value stamped at or before it (:mod:`.history`).
On a loaded machine the input stamped at the same time as a slip may arrive after it (each
topic is delivered in order, but not in step with the others): answered on arrival, that slip
would take an older value, or the nominal one. So a slip is answered only once it is *ready*:
every *live* input has a value stamped at or after the slip's stamp (the topic has passed the
slip's time, so no value at or before it is still in flight).

- An input is live when it has been received and its last arrival (the ROS clock) is within
  the wait bound of now. An input never received, or one that stopped arriving, is not waited
  for: a topic that stops costs at most one wait bound, not a bound per slip.
- A slip that has waited the bound (ROS clock) is released anyway and computed with what there
  is (the fallback rules apply): ``released_by_wait``. So is a slip an input it waited for
  stopped before catching up.
- Order is kept: a slip never overtakes a pending one (the hidden states of an effects file
  step on the slips in order). A slip is answered on arrival, with no extra latency, when
  nothing is pending and it is ready.
- The queue is bounded (:data:`CAPACITY` per wheel): the slip that does not fit releases the
  oldest one (``released_by_overflow``).
- At deactivation and shutdown what is pending is released (``released_by_flush``).

Counters: ``held`` (slips queued) = ``released_caught_up`` + ``released_by_wait`` +
``released_by_overflow`` + ``released_by_flush`` + the ones still pending (:attr:`SlipHold.
pending`, a gauge). ``longest_catch_up_ms``: the longest a slip waited and then got its inputs
(ROS clock; against the bound it says how much margin the bound has).

A wait bound of 0 answers every slip on arrival (no input is live then).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

#: Pending slips per wheel at most: 8 s of a 1 kHz slip topic (at that rate a stopped input
#: releases slips by overflow after 8 s, before the default bound; ~2 MB of slips).
CAPACITY = 8192
#: Why a held slip was released (the counters' names).
RELEASES = (
    "released_caught_up",
    "released_by_wait",
    "released_by_overflow",
    "released_by_flush",
)
HOLD_COUNTS = ("held", *RELEASES)
_NEVER = -(1 << 62)  # arrival of an input never received
_NONE = 1 << 62  # its newest stamp: past every slip, so it never holds one


@dataclass(slots=True)
class PendingSlip:
    """A slip message waiting for its inputs; ``payload`` is the caller's (what to publish)."""

    kappa: float
    alpha: float
    gamma: float
    stamp_ns: int
    arrival_ns: int  # on the ROS clock
    payload: object = None


class SlipHold:
    """One wheel's pending slips and what it knows of its inputs' progress (module docstring).

    Times: ``stamp_ns`` are header stamps; ``now_ns``, arrivals and ``wait_ns`` are the ROS
    clock's.
    """

    def __init__(self, inputs: Sequence[str], capacity: int = CAPACITY) -> None:
        self.inputs = tuple(inputs)
        self.capacity = capacity
        self._index = {name: i for i, name in enumerate(self.inputs)}
        # per input: its newest stamp and its last arrival (lists: zip over two short lists is
        # the cheapest loop here); floor, the oldest newest stamp of the inputs received: a
        # slip stamped at or before it is ready without a look at the clock (the usual case)
        self._seen = [_NONE] * len(self.inputs)
        self._arrived = [_NEVER] * len(self.inputs)
        self.floor = _NONE
        self.queue: deque[PendingSlip] = deque()
        self.counts = dict.fromkeys(HOLD_COUNTS, 0)
        self.longest_catch_up_ns = 0
        self.lagging = ""  # the input the last slip released by the wait lacked

    @property
    def pending(self) -> int:
        return len(self.queue)

    def note(self, name: str, stamp_ns: int, now_ns: int) -> None:
        """Input ``name`` delivered a message stamped ``stamp_ns`` (accepted or rejected: the
        topic has passed that stamp either way) at ``now_ns``."""
        i = self._index[name]
        if stamp_ns > self._seen[i] or self._seen[i] == _NONE:
            self._seen[i] = stamp_ns
            self.floor = min(self._seen)
        self._arrived[i] = now_ns

    def ready(self, stamp_ns: int, now_ns: int, wait_ns: int) -> bool:
        """Whether every live input has reached ``stamp_ns``."""
        if stamp_ns <= self.floor:
            return True
        since = now_ns - wait_ns
        for seen, arrived in zip(self._seen, self._arrived, strict=True):
            if seen < stamp_ns and since < arrived <= now_ns:
                return False
        return True

    def quick(self, stamp_ns: int) -> bool:
        """Whether a slip just arrived may be answered at once whatever the clock says:
        nothing pending, and every input received has reached its stamp (the usual case, a
        comparison; when False, :meth:`arrive` decides)."""
        return stamp_ns <= self.floor and not self.queue

    def admit(self, stamp_ns: int, now_ns: int, wait_ns: int) -> bool:
        """Whether a slip just arrived may be answered at once: nothing pending, and ready."""
        return not self.queue and self.ready(stamp_ns, now_ns, wait_ns)

    def arrive(self, slip: PendingSlip, now_ns: int, wait_ns: int) -> list[PendingSlip]:
        """A slip message arrived: the slips to answer now, in order (it alone when nothing
        is pending and it is ready; else it is queued, and an overflow or the inputs' progress
        may release older ones, or it)."""
        if self.admit(slip.stamp_ns, now_ns, wait_ns):  # the usual case: no extra latency
            return [slip]
        self.counts["held"] += 1
        self.queue.append(slip)
        out = []
        if len(self.queue) > self.capacity:
            self.counts["released_by_overflow"] += 1
            out.append(self.queue.popleft())
        return out + self.release(now_ns, wait_ns)

    def take(self, name: str, stamp_ns: int, now_ns: int, wait_ns: int) -> list[PendingSlip]:
        """An input message arrived (:meth:`note`): the pending slips it made ready."""
        self.note(name, stamp_ns, now_ns)
        return self.release(now_ns, wait_ns) if self.queue else []

    def release(self, now_ns: int, wait_ns: int) -> list[PendingSlip]:
        """The pending slips to answer now, oldest first: from the front, each one ready or
        waited out (a clock that went back counts as waited out: nothing can be told)."""
        out: list[PendingSlip] = []
        queue = self.queue
        while queue:
            slip = queue[0]
            waiting = slip.arrival_ns <= now_ns < slip.arrival_ns + wait_ns
            if waiting and not self.ready(slip.stamp_ns, now_ns, wait_ns):
                break
            queue.popleft()
            reason = self._reason(slip, wait_ns)
            self.counts[reason] += 1
            if reason == "released_caught_up":
                self.longest_catch_up_ns = max(self.longest_catch_up_ns, now_ns - slip.arrival_ns)
            out.append(slip)
        return out

    def _reason(self, slip: PendingSlip, wait_ns: int) -> str:
        """Caught up, unless an input live when the slip arrived has not reached its stamp
        (the slip waited out the bound, or that input stopped)."""
        since = slip.arrival_ns - wait_ns
        for name, seen, arrived in zip(self.inputs, self._seen, self._arrived, strict=True):
            if seen < slip.stamp_ns and arrived > since:
                self.lagging = name
                return "released_by_wait"
        return "released_caught_up"

    def flush(self) -> list[PendingSlip]:
        """Every pending slip, oldest first (deactivation, shutdown)."""
        out = list(self.queue)
        self.queue.clear()
        self.counts["released_by_flush"] += len(out)
        return out
