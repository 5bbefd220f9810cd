"""``tire-model info BAG``: wheels, topics (types, counts, rates), duration, channel ranges.

With ``--salvage`` a damaged or unclosed bag is read as far as it can be trusted, and
``-o OUT`` writes what was recovered as a new, whole bag.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from tire_model_ros.cli.bagarg import add_salvage_argument, print_salvage_report

HELP = "wheels, topics, duration and ranges of a recording"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="rosbag2 folder, .mcap or .db3 file")
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
    bag = read_raw(args.bag, salvage=args.salvage)
    if args.salvage:
        print_salvage_report(bag)
    info = summarize_raw(bag)
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
