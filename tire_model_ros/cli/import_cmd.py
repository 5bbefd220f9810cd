"""``tire-model import FILE -o BAG``: a measurement file (TTC, TYDEX, CSV) as a recording.

The file's channels are converted to SI units and the ISO-W axes, rows with NaN are dropped
and counted, the signs are checked on the data, and the one wheel (prefix P, default
``/rig/wheel``) is written as a normal MCAP bag that ``info``, ``fit``, ``diagnose`` and
``play`` read unchanged. What was read, dropped and checked is printed; a sign check that
fails is a warning on stderr.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "turn a measurement file (TTC .mat/.dat, TYDEX .tdx, CSV) into a recording"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from tire_model_ros.importers import DEFAULT_PREFIX, FORMATS, OMITTABLE

    parser.add_argument("file", metavar="FILE", help="the measurement file")
    parser.add_argument("-o", "--output", required=True, metavar="BAG", help="bag to write")
    parser.add_argument(
        "--format",
        choices=[f.name for f in FORMATS],
        help="file format (default: by suffix: "
        + "; ".join(f"{'/'.join(f.suffixes)} {f.name}" for f in FORMATS)
        + ")",
    )
    parser.add_argument(
        "--omit",
        action="append",
        default=[],
        metavar="CHANNEL",
        help=f"leave a channel out (repeatable or comma list): {', '.join(OMITTABLE)}",
    )
    parser.add_argument(
        "--prefix", default=DEFAULT_PREFIX, metavar="P", help=f"wheel prefix ({DEFAULT_PREFIX})"
    )
    parser.add_argument("--force", action="store_true", help="overwrite BAG")


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.importers import import_file
    from tire_model_ros.recording import write_recording

    source, target = Path(args.file), Path(args.output)
    if target.exists() and not args.force:
        raise FileExistsError(f"{target}: exists; not overwriting it (use --force)")
    if target.resolve() == source.resolve():
        raise ValueError(f"{target}: the output would replace the input file")
    omit = [c.strip() for item in args.omit for c in item.split(",") if c.strip()]
    imported = import_file(source, format=args.format, omit=omit, prefix=args.prefix)
    for line in imported.report.lines:
        print(line)
    for line in imported.report.warnings:
        print(f"tire-model import: warning: {line}", file=sys.stderr)
    s = imported.series
    write_recording(target, [s], overwrite=args.force)
    channels = [
        c for c in ("p", "T", "Vx", "Fx", "Fy", "Mx", "My", "Mz") if getattr(s, c) is not None
    ]
    print(
        f"wrote {target}: wheel {s.prefix}, {len(s)} samples, {s.t[-1] - s.t[0]:.1f} s; "
        f"kappa, alpha, gamma, Fz, {', '.join(channels)}"
    )
    return 0
