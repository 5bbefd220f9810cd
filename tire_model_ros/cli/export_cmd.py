"""``tire-model export BAG -o FILE``: a recording's wheel as a TTC, TYDEX or CSV file.

The inverse of ``import`` (the same channel tables, read backwards): ISO-W axes and SI units
become the format's (SAE axes and metric units for TTC). Time starts at 0 in the file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "write a recording's wheel as a TTC (.mat/.dat), TYDEX (.tdx) or CSV file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from tire_model_ros.importers import FORMATS

    parser.add_argument("bag", metavar="BAG", help="recording (or a measurement file)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="file to write")
    parser.add_argument(
        "--format", choices=[f.name for f in FORMATS], help="file format (default: by suffix)"
    )
    parser.add_argument("--wheel", metavar="PREFIX", help="the wheel (needed if several)")
    parser.add_argument("--force", action="store_true", help="overwrite FILE")


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.importers import MeasurementError, format_named, format_of
    from tire_model_ros.recording import open_recording

    target = Path(args.output)
    fmt = format_named(args.format) if args.format else format_of(target)
    if fmt is None:
        raise MeasurementError(f"{target}: unknown file type; give --format")
    if target.exists() and not args.force:
        raise FileExistsError(f"{target}: exists; not overwriting it (use --force)")
    wheels = open_recording(args.bag, wheels=[args.wheel] if args.wheel else None)
    if len(wheels) > 1:
        raise ValueError(f"{args.bag}: {len(wheels)} wheels ({', '.join(wheels)}); give --wheel")
    series = next(iter(wheels.values()))
    for note in fmt.write(series, target, overwrite=args.force):
        print(note)
    print(f"wrote {target} ({fmt.name}): wheel {series.prefix}, {len(series)} samples")
    return 0
