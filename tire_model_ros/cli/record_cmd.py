"""``tire-model record -o OUT``: record the node's force topics (or any INTERFACE topic)."""

from __future__ import annotations

import argparse

from tire_model_ros.ros import require_ros

HELP = "record the node's force topics to a new bag"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "-o", "--output", required=True, help="new bag: a folder, or a lone .mcap / .db3 file"
    )
    parser.add_argument(
        "--wheels",
        nargs="+",
        default=[],
        metavar="P",
        help="record P/forces of each wheel prefix P",
    )
    parser.add_argument(
        "--topics",
        nargs="+",
        default=[],
        metavar="TOPIC[:TYPE]",
        help="more topics; INTERFACE channel names need no type",
    )
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument("--count", type=int, metavar="N", help="stop after N messages in all")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--force", action="store_true", help="replace OUTPUT if it exists")


def run(args: argparse.Namespace) -> int:
    require_ros("tire-model record")
    from tire_model_ros.ros.record import record, resolve_topics

    topics = resolve_topics(args.topics, args.wheels)
    counts = record(
        args.output,
        topics,
        duration_s=args.duration,
        count=args.count,
        overwrite=args.force,
        storage=args.storage,
    )
    for topic, n in counts.items():
        print(f"{topic}: {n}")
    return 0
