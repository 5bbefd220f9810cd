"""``tire-model info BAG``: wheels, topics (types, counts, rates), duration, channel ranges."""

from __future__ import annotations

import argparse
import json
import os
import sys

HELP = "wheels, topics, duration and ranges of a recording"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="rosbag2 folder, .mcap or .db3 file")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.recording.info import format_summary, summarize

    info = summarize(args.bag)
    text = json.dumps(info, indent=2) if args.json else format_summary(info)
    try:
        print(text)
        sys.stdout.flush()
    except BrokenPipeError:  # `tire-model info BAG | head`: the reader left; not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0
