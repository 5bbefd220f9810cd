"""CLI: python -m realities.brush --list | --case CASE --seed N -o OUTDIR [--minutes M]."""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m realities.brush",
        description="Brush-model tyre on a TTC-like rig programme: "
        "recordings with known missing physics (see README.md).",
    )
    ap.add_argument("--list", action="store_true", help="print the case names")
    ap.add_argument("--case")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("-o", "--out", dest="out")
    ap.add_argument("--minutes", type=float, default=8.0)
    ap.add_argument(
        "--fit",
        nargs="*",
        metavar="VARIANT",
        help="(re)fit model.tir of the tyre variants (all if none given)",
    )
    ap.add_argument("--tyre", help="force the tyre variant (default: drawn from the seed)")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    from . import cases

    if a.list:
        print("\n".join(cases.CASES))
        return 0
    if a.fit is not None:
        from . import fit, tyre

        for name in a.fit or list(tyre.VARIANTS):
            fit.get_fitted(tyre.VARIANTS[name], verbose=True)
        return 0
    if not a.case or not a.out:
        ap.error("--case and -o are required (or --list)")
    if a.minutes <= 0.5:
        ap.error("--minutes must be more than 0.5")
    cases.generate(a.case, a.seed, a.out, a.minutes, quiet=a.quiet, tyre=a.tyre)
    return 0


if __name__ == "__main__":
    sys.exit(main())
