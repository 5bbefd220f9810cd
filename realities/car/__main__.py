"""``python -m realities.car --list`` / ``--case CASE --seed N -o OUTDIR [--minutes M]``."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m realities.car", description="Reality generator 'car': a car on a track."
    )
    ap.add_argument("--list", action="store_true", help="print the case names")
    ap.add_argument("--case")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("-o", "--out", dest="out")
    ap.add_argument("--minutes", type=float, default=8.0)
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    from .cases import CASES

    if a.list:
        print("\n".join(CASES))
        return 0
    if not a.case or not a.out:
        ap.error("--case and -o are required (or --list)")
    if a.minutes <= 0.5:
        ap.error("--minutes must be > 0.5")
    from .generate import generate

    generate(a.case, a.seed, a.out, minutes=a.minutes, verbose=not a.quiet)
    return 0


if __name__ == "__main__":
    sys.exit(main())
