"""``tire-model eval``: evaluate the Magic Formula on every row of a CSV file.

Input columns (header required, any order, extra columns ignored): ``Fz,kappa,alpha,gamma,Vx,p``
and optionally ``phit``, ``T`` (SI units, radians, p gauge [Pa], T [degC]; a missing ``T``
column means NOMTEMP; ``phit`` is used with ``--turn-slip``). The output holds the input columns
plus ``Fx,Fy,Mx,My,Mz``.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from pathlib import Path

import numpy as np

from tire_model_ros.atomic import write_atomic

HELP = "evaluate the model on a CSV of inputs"
REQUIRED = ("Fz", "kappa", "alpha", "gamma", "Vx", "p")
OPTIONAL = ("phit", "T")
OUTPUTS = ("Fx", "Fy", "Mx", "My", "Mz")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="IN.csv", help="CSV with columns " + ",".join(REQUIRED))
    parser.add_argument("--tir", required=True, metavar="FILE", help="tyre property file (.tir)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.csv", help="result CSV")
    parser.add_argument(
        "--no-limits",
        action="store_true",
        help="plain equations: no input saturation, no low-speed model (MFeval useMode 211)",
    )
    parser.add_argument(
        "--turn-slip",
        action="store_true",
        help="turn-slip model, with the phit column (MFeval useMode xx2)",
    )
    parser.add_argument(
        "--alpha-star",
        action="store_true",
        help="alpha* = tan(alpha), gamma* = sin(gamma) in the equations (MFeval useMode x2x)",
    )
    parser.add_argument("--force", action="store_true", help="overwrite OUT.csv if it exists")


def read_inputs(path: Path) -> dict[str, np.ndarray]:
    """Columns of IN.csv as float arrays; ValueError naming file, row and column when bad."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:  # a BOM is no column name
            rows = list(csv.reader(fh))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text CSV file ({exc.reason})") from None
    if not rows:
        raise ValueError(f"{path}: empty file, expected a header with {','.join(REQUIRED)}")
    header = [h.strip() for h in rows[0]]
    missing = [name for name in REQUIRED if name not in header]
    if missing:
        raise ValueError(f"{path}: line 1: missing column(s) {', '.join(missing)}")
    wanted = [name for name in REQUIRED + OPTIONAL if name in header]
    index = {name: header.index(name) for name in wanted}
    data = {name: [] for name in wanted}
    for line_no, row in enumerate(rows[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue  # blank line
        for name in wanted:
            col = index[name]
            if col >= len(row):
                raise ValueError(f"{path}: line {line_no}: column {name!r} missing (short row)")
            try:
                data[name].append(float(row[col]))
            except ValueError:
                raise ValueError(
                    f"{path}: line {line_no}: column {name!r}: {row[col]!r} is not a number"
                ) from None
    return {name: np.asarray(values, dtype=np.float64) for name, values in data.items()}


def write_csv_atomic(path: Path, columns: dict[str, np.ndarray], overwrite: bool) -> None:
    """Write the columns to ``path`` atomically; floats with repr() precision."""
    names = list(columns)
    buf = io.StringIO(newline="")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in zip(*(columns[n] for n in names), strict=True):
        writer.writerow([repr(float(v)) if math.isfinite(v) else str(v) for v in row])
    write_atomic(path, buf.getvalue(), overwrite=overwrite)


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.model import TireModel

    source = Path(args.input)
    target = Path(args.output)
    if target.exists() and not args.force:
        raise FileExistsError(f"{target}: output exists; use --force to overwrite it")
    if target.resolve() == source.resolve():
        raise ValueError(f"{target}: the output would replace the input file")
    if not target.parent.is_dir():
        raise FileNotFoundError(f"{target.parent}: output folder does not exist")
    model = TireModel.from_file(args.tir)
    inputs = read_inputs(source)
    out = model.evaluate(
        inputs["Fz"],
        inputs["kappa"],
        inputs["alpha"],
        inputs["gamma"],
        inputs["Vx"],
        inputs["p"],
        inputs.get("T"),
        phit=inputs.get("phit", 0.0),
        limits=not args.no_limits,
        full=False,
        turn_slip=args.turn_slip,
        alpha_star=args.alpha_star,
    )
    columns = dict(inputs)
    columns.update({name: getattr(out, name) for name in OUTPUTS})
    write_csv_atomic(target, columns, overwrite=args.force)
    print(f"wrote {target}: {inputs['Fz'].size} rows")
    return 0
