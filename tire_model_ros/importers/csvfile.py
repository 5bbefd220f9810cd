"""CSV tables (a test's export, an FE model's output): the columns of ``tire-model eval``.

A header line, then one row per sample, comma separated, already in the project's SI units
and ISO-W axes (INTERFACE.md): ``t`` [s], ``Fz`` [N], ``kappa`` [-], ``alpha``, ``gamma``
[rad], ``Vx`` [m/s], ``p`` [Pa gauge], ``T`` [degC]; the measured ``Fx``, ``Fy`` [N], ``Mx``,
``My``, ``Mz`` [N m]. ``t``, ``Fz``, ``kappa``, ``alpha``, ``gamma`` and one measured force
are needed; a recording without ``Vx``, ``p`` or ``T`` takes the model's nominal values.
Columns may come in any order; others are ignored. A UTF-8 byte-order mark (spreadsheet
exports) is read as such; empty cells and ``nan`` are NaN (the rows are dropped and counted by
the import).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from tire_model_ros.atomic import write_atomic
from tire_model_ros.recording.series import WheelSeries

from .base import Columns, MeasurementError, parse_rows

REQUIRED = ("t", "Fz", "kappa", "alpha", "gamma")
OPTIONAL = ("Vx", "p", "T", "Fx", "Fy", "Mx", "My", "Mz")  # at least one force (the import)


def read_table(
    path: Path, required: tuple[str, ...], optional: tuple[str, ...] = ()
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The named columns of a CSV file as floats, and each row's line number.

    Raises
    ------
    MeasurementError
        Not text, no header, a missing column (line 1), a short row or a cell that is not a
        number (its line and column).
    """
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except UnicodeDecodeError as exc:
        raise MeasurementError(f"{path}: not a text CSV file ({exc.reason})") from None
    if not rows:
        raise MeasurementError(f"{path}: empty file, expected a header with {','.join(required)}")
    header = [h.strip() for h in rows[0]]
    missing = [name for name in required if name not in header]
    if missing:
        raise MeasurementError(f"{path}: line 1: missing column(s) {', '.join(missing)}")
    wanted = [name for name in (*required, *optional) if name in header]
    body = [(no, r) for no, r in enumerate(rows[1:], start=2) if any(c.strip() for c in r)]
    for no, r in body:
        if len(r) < len(header):
            short = header[len(r)] if len(r) < len(header) else ""
            raise MeasurementError(f"{path}: line {no}: column {short!r} missing (short row)")
    picked = [(no, [r[header.index(name)] for name in wanted]) for no, r in body]
    try:
        data = parse_rows(path, picked, len(wanted))
    except MeasurementError as exc:  # name the column, not its position among the picked
        text = str(exc)
        for j, name in enumerate(wanted, start=1):
            text = text.replace(f": column {j}: ", f": column {name!r}: ")
        raise MeasurementError(text) from None
    lines = np.array([no for no, _ in picked], np.int64)
    return {name: data[:, j] for j, name in enumerate(wanted)}, lines


class CsvFormat:
    """The CSV table format (see the module text)."""

    name: str = "csv"
    suffixes: tuple[str, ...] = (".csv",)
    description: str = "CSV table: t,Fz,kappa,alpha,gamma,Vx,p[,T],Fx,Fy[,Mx,My,Mz], SI, ISO-W"

    def read(self, path: Path) -> Columns:
        """The table's columns (already SI and ISO-W)."""
        table, lines = read_table(path, REQUIRED, OPTIONAL)
        t = table.pop("t")
        return Columns(path, self.name, t, table, {c: c for c in (*REQUIRED, *OPTIONAL)}, lines)

    def write(self, series: WheelSeries, path: Path, *, overwrite: bool = False) -> list[str]:
        """Write ``series`` as such a table; ``t`` is the time since the first sample."""
        cols = {"t": series.t - series.t[0]}
        for name in (*REQUIRED[1:], *OPTIONAL):
            v = getattr(series, name)
            if v is not None:
                cols[name] = v
        buf = io.StringIO(newline="")
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(list(cols))
        for row in zip(*cols.values(), strict=True):
            writer.writerow([repr(float(v)) if math.isfinite(v) else "nan" for v in row])
        write_atomic(path, buf.getvalue(), overwrite=overwrite)
        return []
