"""Measurement files in: TTC, TYDEX and CSV files as the aligned arrays of a recording.

No ROS here. Each format is one class in its own module (``ttc``, ``tydex``, ``csvfile``) with
``name``, ``suffixes``, ``read(path) -> Columns`` and ``write(series, path)``; :data:`FORMATS`
lists them and everything else loops over it. :func:`import_file` reads a file into a
:class:`~tire_model_ros.recording.series.WheelSeries` through the one pipeline of
``base.to_series`` (omit, NaN rows, time, sign checks); ``tire-model import`` writes that as a
normal bag, and ``fit`` / ``diagnose`` open such files directly
(:func:`tire_model_ros.recording.open.open_recording`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

from tire_model_ros.recording.series import WheelSeries

from .base import DEFAULT_PREFIX, OMITTABLE, Columns, Imported, ImportReport, MeasurementError
from .csvfile import CsvFormat
from .ttc import TtcFormat
from .tydex import TydexFormat


class MeasurementFormat(Protocol):
    """One file format: how it is named, recognised, read and written."""

    name: str
    suffixes: tuple[str, ...]
    description: str

    def read(self, path: Path) -> Columns: ...

    def write(self, series: WheelSeries, path: Path, *, overwrite: bool = False) -> list[str]: ...


FORMATS: tuple[MeasurementFormat, ...] = (TtcFormat(), TydexFormat(), CsvFormat())


def format_named(name: str) -> MeasurementFormat:
    """The format called ``name``; MeasurementError listing the known ones."""
    for f in FORMATS:
        if f.name == name:
            return f
    raise MeasurementError(f"unknown format {name!r} (known: {', '.join(f.name for f in FORMATS)})")


def format_of(path: str | os.PathLike[str]) -> MeasurementFormat | None:
    """The format a file's suffix names (``.mat``/``.dat`` TTC, ``.tdx``, ``.csv``), else None."""
    suffix = Path(path).suffix.lower()
    return next((f for f in FORMATS if suffix in f.suffixes), None)


def import_file(
    path: str | os.PathLike[str],
    *,
    format: str | None = None,
    omit: Sequence[str] = (),
    prefix: str = DEFAULT_PREFIX,
) -> Imported:
    """Read a measurement file into one wheel's aligned samples, with the import report.

    Parameters
    ----------
    path : the file.
    format : a name of :data:`FORMATS`; None: by the file's suffix.
    omit : channels to leave out (``OMITTABLE`` words: temperature, pressure, velocity,
        moments).
    prefix : the wheel's topic prefix (default ``/rig/wheel``).

    Raises
    ------
    MeasurementError
        One line naming the file, the line or channel, and what is wrong.
    """
    file = Path(path)
    fmt = format_named(format) if format else format_of(file)
    if fmt is None:
        known = ", ".join(f"{s} ({f.name})" for f in FORMATS for s in f.suffixes)
        raise MeasurementError(f"{file}: unknown file type; give --format ({known})")
    if not file.is_file():
        raise MeasurementError(f"{file}: no such file")
    from .base import to_series

    return to_series(fmt.read(file), omit=omit, prefix=prefix)


__all__ = [
    "DEFAULT_PREFIX",
    "FORMATS",
    "OMITTABLE",
    "Columns",
    "ImportReport",
    "Imported",
    "MeasurementError",
    "MeasurementFormat",
    "format_named",
    "format_of",
    "import_file",
]
