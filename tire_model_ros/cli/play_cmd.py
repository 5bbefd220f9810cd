"""``tire-model play BAG``: publish a recording's input topics with their original timing."""

from __future__ import annotations

import argparse
import signal
from types import FrameType

from tire_model_ros.cli.bagarg import add_salvage_argument
from tire_model_ros.ros import require_ros

HELP = "publish a recording's input topics with their timing"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="rosbag2 folder, .mcap or .db3 file")
    parser.add_argument(
        "--rate",
        type=float,
        default=1.0,
        help="time scale: 2 = twice as fast, 0 = as fast as possible",
    )
    parser.add_argument("--fast", action="store_true", help="as fast as possible (= --rate 0)")
    parser.add_argument("--loop", action="store_true", help="start again at the end")
    parser.add_argument("--wheels", nargs="+", metavar="P", help="only these wheel prefixes")
    parser.add_argument(
        "--measured",
        action="store_true",
        help="also publish P/measured_forces (not an input of the node)",
    )
    parser.add_argument(
        "--queue",
        type=int,
        default=1000,
        help="publisher history depth (reliable QoS); default 1000",
    )
    parser.add_argument(
        "--wait",
        type=float,
        default=2.0,
        metavar="S",
        help="wait up to S seconds for subscribers before starting",
    )
    add_salvage_argument(parser)


def run(args: argparse.Namespace) -> int:
    require_ros("tire-model play")
    from tire_model_ros.ros.play import play

    if args.queue < 1:
        raise ValueError(f"--queue must be >= 1, got {args.queue}")
    stop = {"flag": False}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop["flag"] = True

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    report = play(
        args.bag,
        rate=0.0 if args.fast else args.rate,
        loop=args.loop,
        wheels=args.wheels,
        measured=args.measured,
        queue=args.queue,
        wait_subscribers_s=args.wait,
        should_stop=lambda: stop["flag"],
        salvage=args.salvage,
    )
    for line in report.lines():
        print(line)
    print(f"published {report.total} messages")
    return 0
