"""A deadline on ROS teardown, for the processes this package runs (node, play, record).

Fast DDS can deadlock deleting a reader or writer while a peer process is going away
(eProsima/Fast-DDS#6193). Seen once in CI: a recorder stopped by ``--count`` as its player
exited had closed its bag but never finished tearing ROS down. A call into rclpy's C++ may hold
the GIL, so neither a Python thread nor a signal handler can be relied on to time it out.
faulthandler's watchdog is a C thread that needs no GIL: when the deadline passes it writes
every thread's stack to stderr and exits with status 1. Callers arm it only once their data are
safe (the bag closed, the messages acknowledged), so status 1 then means "done, but DDS hung".
"""

from __future__ import annotations

import faulthandler
from collections.abc import Iterator
from contextlib import contextmanager

TEARDOWN_S = 10.0


@contextmanager
def deadline(seconds: float = TEARDOWN_S) -> Iterator[None]:
    """Exit the process (status 1, all stacks on stderr) if the block outlasts ``seconds``.

    faulthandler has one such timer per process: do not nest this.
    """
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
