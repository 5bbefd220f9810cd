"""Open what a user calls a recording: a bag, or a measurement file imported on the fly.

The offline commands (``fit``, ``diagnose`` through ``cli.bagarg.read_wheels``, ``export``)
open their inputs here, so every command takes a TTC, TYDEX or CSV file wherever it takes a
bag, and the import's report (rows dropped, sign checks, warnings) is said the same way
everywhere.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence

from tire_model_ros.recording.series import WheelSeries


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)


def open_recording(
    path: str | os.PathLike[str],
    wheels: Sequence[str] | None = None,
    *,
    say: Callable[[str], None] = _stderr,
) -> dict[str, WheelSeries]:
    """The wheels of a recording: a rosbag2 folder / .mcap / .db3 (``read_recording``) or a
    measurement file (``.mat``/``.dat`` TTC, ``.tdx`` TYDEX, ``.csv``; one wheel, prefix
    ``/rig/wheel``), whose import report goes to ``say`` (stderr), warnings prefixed.

    Raises
    ------
    RecordingError, MeasurementError (both ValueError)
        Unreadable input, named with the file and what is wrong; a wheel asked for that is not
        in it.
    """
    from tire_model_ros.importers import MeasurementError, format_of, import_file

    if format_of(path) is None:
        from tire_model_ros.recording.read import read_recording

        return read_recording(path, wheels=wheels)
    imported = import_file(path)
    for line in imported.report.lines:
        say(f"import: {line}")
    for line in imported.report.warnings:
        say(f"import: warning: {line}")
    s = imported.series
    if wheels is not None and s.prefix not in wheels:
        raise MeasurementError(f"{path}: one wheel, {s.prefix}; not {', '.join(wheels)}")
    return {s.prefix: s}
