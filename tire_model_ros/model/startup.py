"""The kernels made ready before a process needs them, saying so when that means compiling.

``make venv``, ``setup.py install``/``develop`` (what colcon runs) compile the kernels into
numba's cache when the package is installed (:func:`tire_model_ros.model.kernel.warm_up`). An
install that could not (a pip wheel: no install hook; a read-only site-packages) compiles them
on the first start instead, 35 s of CPU here and more on a busy machine: :func:`warm_up_announced`
then says what is happening and for how long, instead of a silent minute.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

#: Seconds a load may take before the notice is printed when numba's cache holds the kernels
#: (a cached load takes ~0.3 s; a cache from other sources is dropped and compiled again).
NOTICE_AFTER_S = 5.0
COMPILE_NOTICE = (
    "compiling the Magic Formula kernels into numba's cache (not done at install time here): "
    "about 35 s of CPU once, longer on a busy machine; later starts load them in under a second"
)


def warm_up_announced(
    log: Callable[[str], None] = print,
    notice_after_s: float = NOTICE_AFTER_S,
    load: Callable[[], object] | None = None,
) -> float:
    """Load or compile the kernels (``load``, default ``kernel.warm_up``); seconds taken.

    ``log`` gets :data:`COMPILE_NOTICE` at once when numba's cache has no kernels, else when the
    load takes longer than ``notice_after_s``; and then a line with the time taken at the end.
    """
    if load is None:
        from tire_model_ros.model.kernel import warm_up

        load = warm_up
    start = time.monotonic()
    said: list[str] = []

    def notice() -> None:
        said.append(COMPILE_NOTICE)
        log(COMPILE_NOTICE)

    timer = threading.Timer(0.0 if not cache_present() else notice_after_s, notice)
    timer.daemon = True
    timer.start()
    try:
        load()
    finally:
        timer.cancel()
    took = time.monotonic() - start
    if said:
        log(f"kernels ready after {took:.0f} s (cached for later starts)")
    return took


def cache_present() -> bool:
    """Whether numba's cache (in any place it may use) holds the single-sample kernel."""
    from tire_model_ros.model.jit import _cache_dirs  # numba's places, as the cache guard's

    return any(any(d.glob("kernel.evaluate_point-*.nbi")) for d in _cache_dirs() if d.is_dir())
