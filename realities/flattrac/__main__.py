"""Command line: --list, or --case CASE --seed N -o OUTDIR [--minutes M]."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m realities.flattrac", description="Flat-Trac-like reality generator"
    )
    ap.add_argument("--list", action="store_true", help="print the case names")
    ap.add_argument("--case")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("-o", "--out")
    ap.add_argument("--minutes", type=float, default=8.0)
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    from .cases import CASES

    if a.list:
        print("\n".join(CASES))
        return 0
    if not a.case or not a.out:
        ap.error("--case and -o are required (or --list)")
    if a.case not in CASES:
        ap.error(f"unknown case {a.case!r}; one of: {', '.join(CASES)}")
    if a.minutes <= 0:
        ap.error("--minutes must be positive")
    from .make import generate

    try:
        generate(a.case, a.seed, a.out, minutes=a.minutes, quiet=a.quiet)
    except FileExistsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
