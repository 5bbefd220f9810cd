"""``--salvage``: the option of every command that reads bags, and reading with it."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tire_model_ros.recording import RawBag, WheelSeries

SALVAGE_HELP = (
    "read a damaged or unclosed bag instead of refusing it: skip the chunks whose CRC fails, "
    "recover the complete chunks of an interrupted recording (its recorder's temporary folder "
    "too), and say what was skipped and recovered, per topic"
)


def add_salvage_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--salvage", action="store_true", help=SALVAGE_HELP)


def print_salvage_report(bag: RawBag) -> None:
    """What a salvaging read skipped and recovered, one line each, on stderr."""
    for line in bag.salvage_report():
        print(f"salvage: {line}", file=sys.stderr)


def read_wheels(
    path: str | os.PathLike[str], wheels: Sequence[str] | None = None, salvage: bool = False
) -> dict[str, WheelSeries]:
    """``read_recording`` that prints the salvage report (with ``salvage``) before aligning;
    a measurement file (TTC, TYDEX, CSV) is imported on the fly (``open_recording``; it is no
    bag, so there is nothing to salvage)."""
    from tire_model_ros.importers import format_of
    from tire_model_ros.recording import open_recording, read_raw, wheels_from_raw
    from tire_model_ros.recording.read import wheel_select

    if format_of(path) is not None:
        return open_recording(path, wheels)
    raw = read_raw(path, wheel_select(wheels), salvage=salvage)
    if salvage:
        print_salvage_report(raw)
    return wheels_from_raw(raw, wheels)
