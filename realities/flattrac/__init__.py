"""flattrac: an independent Flat-Trac-like rig generator (one wheel, prefix /rig/wheel).

``python -m realities.flattrac --list`` and
``python -m realities.flattrac --case CASE --seed N -o OUTDIR [--minutes M]``.
See README.md for the physics forms, parameter ranges, programme and cases.
"""

from .cases import CASES

__all__ = ["CASES", "generate"]


def generate(case, seed, outdir, minutes=8.0, quiet=False):
    from .make import generate as _generate

    return _generate(case, seed, outdir, minutes=minutes, quiet=quiet)
