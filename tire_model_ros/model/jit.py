"""The numba decorators of the Magic Formula kernels, and their cache guard.

``kernel`` (an equation: scalars in, scalars out) is inlined into its caller at numba level
(``inline="always"``), so that the sample loops of :mod:`.kernel` contain no calls and LLVM
vectorises them; ``standalone`` is compiled on its own: the sample loops, and the vertical
equations that the (unvectorised) loop of the full outputs calls.
``error_model="numpy"``: a division by zero gives inf/NaN like numpy instead of raising, so bad
inputs cannot crash an evaluation. No fastmath: the oracle comparison needs IEEE arithmetic, and
the results must not depend on the machine (:mod:`.vmath` fuses its multiply-adds explicitly,
with ``llvm.fma``: a fastmath flag on an inlined function is lost, the caller's flags apply).
``cache=True``: compiled code is stored in ``__pycache__`` beside the sources and reused by
later processes.

Two code-generation settings, for every numba function the process compiles afterwards:

- LLVM interleaves a vectorised loop up to 4 times when its cost model likes it; on the long
  bodies of these loops that makes the compile take minutes instead of seconds.
  ``-force-vector-interleave=1`` stops that unrolling.
- LLVM's tuning for AVX-512 Intel cores prefers 256-bit vectors; the stage loops are bound by
  arithmetic and run about 1.4x faster on 512-bit ones, so ``-prefer-256-bit`` is switched off
  (no effect on a CPU without AVX-512; a NUMBA_CPU_FEATURES set by the user is kept).

numba keys a cached function on its own source file only: a kernel in ``kernel.py`` compiled
with an older ``forces.py`` would be loaded stale after ``forces.py`` changed. The guard below
hashes every kernel source of this package and drops the package's numba cache (in every
directory numba may use for it, ``NUMBA_CACHE_DIR`` included) when the hash differs from the
one the cache was built with.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import llvmlite.binding as llvm
from numba import config, njit

_HERE = Path(__file__).resolve().parent
_SOURCES = ("jit.py", "coef.py", "conditions.py", "forces.py", "moments.py", "turnslip.py",
            "vertical.py", "kernel.py", "vmath.py")  # fmt: skip


def _sources_digest() -> str:
    h = hashlib.sha256()
    for name in _SOURCES:
        try:
            h.update((_HERE / name).read_bytes())
        except OSError:
            h.update(name.encode())
    return h.hexdigest()


def _cache_dirs() -> list[Path]:
    """Where numba may keep this package's cache, in its own order of choice.

    ``NUMBA_CACHE_DIR`` when set, else ``__pycache__`` beside the sources, else (a read-only
    install) the user-wide cache; numba's own subpath rule names the directory in the first
    and last (its internal API: when it moves, only the in-tree directory is guarded).
    """
    in_tree = _HERE / "__pycache__"
    try:
        from numba.core.caching import _CacheLocator
        from numba.misc.appdirs import AppDirs

        sub = _CacheLocator.get_suitable_cache_subpath(str(_HERE / "kernel.py"))
        user_wide = Path(AppDirs("numba", appauthor=False).user_cache_dir) / sub
    except (ImportError, AttributeError, TypeError):
        return [in_tree]
    first = [Path(config.CACHE_DIR) / sub] if config.CACHE_DIR else []
    return [*first, in_tree, *([user_wide] if user_wide.is_dir() else [])]


def _guard_cache() -> None:
    """Remove this package's numba cache files where they were built from other sources."""
    digest = _sources_digest()
    for cache in _cache_dirs():
        stamp = cache / "mf_kernels.sha256"
        try:
            if stamp.read_text() == digest:
                continue
        except OSError:
            pass
        try:
            cache.mkdir(parents=True, exist_ok=True)
            for f in cache.iterdir():
                if f.suffix in (".nbi", ".nbc"):
                    f.unlink(missing_ok=True)
            tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
            tmp.write_text(digest)
            os.replace(tmp, stamp)
        except OSError:
            pass  # not writable: numba does not use it either


_guard_cache()
llvm.set_option("tire_model_ros", "-force-vector-interleave=1")
if config.CPU_FEATURES is None:
    config.CPU_FEATURES = llvm.get_host_cpu_features().flatten() + ",-prefer-256-bit"

kernel = njit(cache=True, error_model="numpy", inline="always")
standalone = njit(cache=True, error_model="numpy")
vkernel = kernel
"""The decorator of :mod:`.vmath` (``kernel``)."""
