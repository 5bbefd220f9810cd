"""``tire-model info BAG``: wheels, topics (types, counts, rates), duration, channel ranges.

With ``--salvage`` a damaged or unclosed bag is read as far as it can be trusted, and
``-o OUT`` writes what was recovered as a new, whole bag. A measurement file (TTC, TYDEX,
CSV) is summarised as the bag ``tire-model import`` would write of it (imported on the fly,
as ``fit`` and ``diagnose`` open it; the import report on stderr).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from tire_model_ros.cli.bagarg import add_salvage_argument, print_salvage_report

if TYPE_CHECKING:
    from tire_model_ros.recording import RawBag

HELP = "wheels, topics, duration and ranges of a recording"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "bag",
        help="rosbag2 folder, .mcap or .db3 file, or a measurement file (.mat/.dat TTC, .tdx "
        "TYDEX, .csv) imported on the fly",
    )
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_salvage_argument(parser)
    parser.add_argument(
        "-o",
        "--output",
        metavar="OUT",
        help="with --salvage: write the recovered messages as a new bag OUT (a folder, or a "
        "lone .mcap file)",
    )
    parser.add_argument("--force", action="store_true", help="replace OUT if it exists")


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.recording import read_raw
    from tire_model_ros.recording.info import format_summary, summarize_raw
    from tire_model_ros.recording.salvage import write_raw

    if args.output and not args.salvage:
        raise ValueError("-o/--output writes what --salvage recovered: give --salvage too")
    from tire_model_ros.importers import format_of

    if format_of(args.bag) is not None:
        if args.salvage:
            raise ValueError(f"{args.bag}: a measurement file, not a bag: nothing to salvage")
        bag = _imported(args.bag)
    else:
        bag = read_raw(args.bag, salvage=args.salvage)
    if args.salvage:
        print_salvage_report(bag)
    info = summarize_raw(bag)
    if bag.path != Path(args.bag):
        fmt = format_of(args.bag)
        info.update(path=args.bag, storage=f"{fmt.name if fmt else '?'} file, imported")
    text = json.dumps(info, indent=2) if args.json else format_summary(info)
    try:
        print(text)
        sys.stdout.flush()
    except BrokenPipeError:  # `tire-model info BAG | head`: the reader left; not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    if args.output:
        write_raw(bag, args.output, overwrite=args.force)
        print(f"wrote {args.output}: {bag.messages_read} messages recovered", file=sys.stderr)
    return 0


def _imported(path: str) -> RawBag:
    """The raw bag ``tire-model import`` would write of a measurement file (written to a
    temporary folder and read back whole, so the summary is the bag's)."""
    from tire_model_ros.recording import open_recording, read_raw, write_recording

    wheels = open_recording(path)
    with tempfile.TemporaryDirectory(prefix="tire-model-info-") as tmp:
        write_recording(Path(tmp) / "bag", list(wheels.values()))
        return read_raw(Path(tmp) / "bag")
