"""Process-wide latency settings of a node process (no ROS import, Linux).

A node that answers every slip sample within a millisecond or two shares the CPU with the
simulator and everything else; on a loaded machine its tail latency is set by the scheduler,
not by its own work (``bench/bench_node.py``). Three settings remove what is not inherent:

- ``rt_priority``: SCHED_FIFO at that priority (1..99) for every thread of the process, the
  DDS receive threads included, so a wake-up runs at once instead of waiting behind normal
  processes; needs root or CAP_SYS_NICE (else a warning and normal scheduling).
- ``cpus``: CPU affinity of every thread (e.g. a core kept free for the node).
- ``freeze_heap``: after start-up the heap holds ~130k objects (rclpy, numba, the model); one
  full collection of them takes 16-54 ms. ``gc.freeze`` moves them out of the collector's view,
  so later collections only scan what is new (a few µs).

Threads created afterwards inherit policy and affinity from the thread that creates them.
"""

from __future__ import annotations

import gc
import os
from collections.abc import Sequence

MAX_RT_PRIORITY = 99


def thread_ids() -> list[int]:
    """Kernel ids of every thread of this process."""
    return [int(t) for t in os.listdir("/proc/self/task")]


def apply(rt_priority: int = 0, cpus: Sequence[int] = ()) -> list[str]:
    """Set SCHED_FIFO ``rt_priority`` (0 = leave as is) and affinity ``cpus`` (empty = leave).

    Applies to every thread of the process. Returns the problems (e.g. no permission) as
    messages instead of raising: the node then runs with normal scheduling.
    """
    problems: list[str] = []
    if not 0 <= rt_priority <= MAX_RT_PRIORITY:
        return [f"rt_priority {rt_priority} outside 0..{MAX_RT_PRIORITY}: not applied"]
    wanted = {int(c) for c in cpus}
    if wanted and not wanted <= os.sched_getaffinity(0):
        problems.append(f"cpus {sorted(wanted)} not all available: affinity not applied")
        wanted = set()
    for tid in thread_ids():
        try:
            if wanted:
                os.sched_setaffinity(tid, wanted)
            if rt_priority:
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(rt_priority))
        except ProcessLookupError:  # the thread has just ended
            continue
        except OSError as exc:
            problems.append(f"SCHED_FIFO {rt_priority} / cpus {sorted(wanted)}: {exc.strerror}")
            break
    return problems


def freeze_heap() -> None:
    """Collect once, then exclude every object alive now from later collections."""
    gc.collect()
    gc.freeze()


def tune(rt_priority: int = 0, cpus: Sequence[int] = ()) -> list[str]:
    """What a latency-sensitive process does once set up: ``apply``, then ``freeze_heap``.

    Returns the problems of ``apply``.
    """
    problems = apply(rt_priority, cpus)
    freeze_heap()
    return problems
