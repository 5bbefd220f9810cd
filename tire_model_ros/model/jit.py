"""The numba decorators of the Magic Formula kernels, and their cache guard.

``kernel`` (an equation: scalars in, scalars out) is inlined into its caller at numba level
(``inline="always"``), so that the sample loops of :mod:`.kernel` contain no calls and LLVM
vectorises them; ``driver`` (a loop over samples) is compiled on its own.
``error_model="numpy"``: a division by zero gives inf/NaN like numpy instead of raising, so bad
inputs cannot crash an evaluation. No fastmath: the oracle comparison needs IEEE arithmetic
(:mod:`.vmath` alone allows FMA contraction).
``cache=True``: compiled code is stored in ``__pycache__`` beside the sources and reused by
later processes.

LLVM interleaves a vectorised loop up to 4 times when its cost model likes it; on the long
bodies of these loops that makes the compile take minutes instead of seconds, and buys nothing
(the bodies have plenty of independent work). ``-force-vector-interleave=1`` is set for the
process: it only stops that unrolling, for every numba loop compiled afterwards.

numba keys a cached function on its own source file only: a kernel in ``kernel.py`` compiled
with an older ``forces.py`` would be loaded stale after ``forces.py`` changed. The guard below
hashes every kernel source of this package and drops the package's numba cache when the hash
differs from the one the cache was built with.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import llvmlite.binding as llvm
from numba import njit

_HERE = Path(__file__).resolve().parent
_SOURCES = ("jit.py", "coef.py", "conditions.py", "forces.py", "moments.py",
            "vertical.py", "kernel.py", "vmath.py")  # fmt: skip


def _sources_digest() -> str:
    h = hashlib.sha256()
    for name in _SOURCES:
        try:
            h.update((_HERE / name).read_bytes())
        except OSError:
            h.update(name.encode())
    return h.hexdigest()


def _guard_cache() -> None:
    """Remove this package's numba cache files if they were built from other sources."""
    cache = _HERE / "__pycache__"
    stamp = cache / "mf_kernels.sha256"
    digest = _sources_digest()
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for f in cache.iterdir():
            if f.suffix in (".nbi", ".nbc"):
                f.unlink(missing_ok=True)
        tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
        tmp.write_text(digest)
        os.replace(tmp, stamp)
    except OSError:
        pass  # read-only install: numba then compiles in memory or uses its own cache dir


_guard_cache()
llvm.set_option("tire_model_ros", "-force-vector-interleave=1")

kernel = njit(cache=True, error_model="numpy", inline="always")
driver = njit(cache=True, error_model="numpy")
