"""The ``--lenient`` flag of every command that reads a .tir file, and the reading itself."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel

LENIENT_HELP = (
    "read a .tir file that lacks coefficients its FITTYP needs (each filled with its documented "
    "default and listed), has unknown sections or no line end after its last line; values, "
    "ranges and the model's finiteness are checked all the same"
)


def add_lenient_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--lenient`` (see :data:`LENIENT_HELP`)."""
    parser.add_argument("--lenient", action="store_true", help=LENIENT_HELP)


def load_model(path: str | os.PathLike[str], lenient: bool) -> TireModel:
    """The model of a .tir file; with ``lenient``, what was let through is printed to stderr."""
    from tire_model_ros.model import TireModel

    model = TireModel.from_file(path, lenient=lenient)
    for note in model.tir.notes:
        print(f"note: {note}", file=sys.stderr)
    return model
