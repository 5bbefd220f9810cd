"""One BLAS thread while the package's small dense problems are solved.

Least-squares Jacobians of a few thousand rows by a few dozen columns: a BLAS thread pool only
costs there, and on a busy machine a lot (a threaded SVD of 3000 x 16 took 0.4 s against
1.5 ms on one thread; a diagnosis 13 min of CPU against 37 s when numpy had been imported
before this package, whose ``__init__`` sets the thread variables only for a later import).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

P = ParamSpec("P")
R = TypeVar("R")


def one_blas_thread(func: Callable[P, R]) -> Callable[P, R]:
    """``func`` run with BLAS limited to one thread (restored after)."""
    wrapped: Callable[P, R] = threadpool_limits.wrap(limits=1, user_api="blas")(func)
    return wrapped
