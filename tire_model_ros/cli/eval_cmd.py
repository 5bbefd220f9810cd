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
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tire_model_ros.atomic import write_atomic
from tire_model_ros.cli.tirarg import add_lenient_argument, load_model
from tire_model_ros.importers.csvfile import read_table
from tire_model_ros.vocabulary import FORCE_CHANNELS

if TYPE_CHECKING:
    from tire_model_ros.model import TireModel

Array = npt.NDArray[np.float64]

HELP = "evaluate the model on a CSV of inputs"
REQUIRED = ("Fz", "kappa", "alpha", "gamma", "Vx", "p")
OPTIONAL = ("phit", "T")
SHOWN_ROWS = 5  # CSV lines named in a refusal
RULE = """\
every row written is finite, or nothing is written:
  - an input cell that is not a finite number (text, nan, inf) stops eval (exit 1), naming its
    line and column;
  - with the limits (the default) the inputs are saturated to the file's ranges
    (FZMIN..FZMAX, KPUMIN..KPUMAX, ALPMIN..ALPMAX, CAMMIN..CAMMAX, PRESMIN..PRESMAX; a
    negative Fz reads as 0) and below VXLOW the low-speed model applies: eval prints how many
    rows each input was saturated on;
  - a row whose outputs are not finite (the plain equations of --no-limits far outside the
    file's ranges, or a coefficient set that breaks there) stops eval (exit 1): nothing is
    written and the message counts those rows and names the first CSV lines;
  - a .tir written by `tire-model fit` carries the envelope its fitted data covered
    ([FIT_ENVELOPE]: load, pressure, temperature): rows outside it are evaluated all the same
    (extrapolation, not saturation) and eval warns with their count and first CSV lines.
The .tir file is refused (exit 1) when it cannot be trusted: see --lenient."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = RULE
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
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
    add_lenient_argument(parser)


def read_inputs(path: Path) -> tuple[dict[str, Array], npt.NDArray[np.int64]]:
    """Columns of IN.csv as float arrays and the CSV line of each row (the importers' CSV
    reader, :func:`~tire_model_ros.importers.csvfile.read_table`), every cell finite.

    Raises
    ------
    ValueError
        naming the file, the line and the column: a missing column, a short row, a cell that
        is not a finite number, a file that is not text.
    """
    columns, lines = read_table(path, REQUIRED, OPTIONAL)
    bad = [(int(np.argmin(np.isfinite(v))), name) for name, v in columns.items()
           if not np.isfinite(v).all()]  # fmt: skip
    if bad:
        row, name = min(bad)  # the first line with a non-finite cell
        value = float(columns[name][row])
        what = " (the cell is empty or NaN)" if np.isnan(value) else ""
        raise ValueError(
            f"{path}: line {lines[row]}: column {name!r}: '{value}' is not finite{what}"
        )
    return columns, lines


def non_finite_rows(outputs: Mapping[str, Array]) -> npt.NDArray[np.bool_]:
    """Rows where any output is NaN or infinite."""
    bad = np.zeros(len(next(iter(outputs.values()))), dtype=bool)
    for values in outputs.values():
        bad |= ~np.isfinite(values)
    return bad


def _refusal(
    path: Path,
    bad: npt.NDArray[np.bool_],
    lines: npt.NDArray[np.int64],
    outputs: Mapping[str, Array],
) -> str:
    """One line: how many rows are not finite, in which outputs, the first CSV lines."""
    where = ", ".join(str(n) for n in lines[bad][:SHOWN_ROWS])
    more = ", ..." if bad.sum() > SHOWN_ROWS else ""
    which = ", ".join(name for name, v in outputs.items() if not np.isfinite(v).all())
    return (
        f"{path}: {int(bad.sum())} of {bad.size} rows give non-finite outputs ({which}) at "
        f"line(s) {where}{more}; nothing written"
    )


def _saturation_note(model_params: Mapping[str, float], inputs: Mapping[str, Array]) -> str:
    from tire_model_ros.model.check import saturated_rows

    counts = saturated_rows(model_params, inputs)
    touched = [f"{name} on {n} row{'s' if n > 1 else ''}" for name, n in counts.items() if n]
    return "saturated to the file's ranges: " + ", ".join(touched) if touched else "none saturated"


def _envelope_warning(
    model: TireModel, inputs: Mapping[str, Array], lines: npt.NDArray[np.int64]
) -> str:
    """Rows outside the fitted envelope of the .tir: a warning on stderr, and the count for
    the summary line ("no envelope" when the file carries none)."""
    from tire_model_ros.model.envelope import Envelope

    try:
        env = Envelope.from_tir(model.tir)
    except ValueError as exc:  # the coefficients are fine: evaluate, but say it loudly
        print(f"warning: {exc}; the envelope is not checked", file=sys.stderr)
        return "envelope unreadable"
    if env is None:
        return "no fitted envelope in the .tir"
    T = inputs.get("T")
    T = np.full(inputs["Fz"].shape, model.params["NOMTEMP"]) if T is None else T
    outside = ~env.contains(inputs["Fz"], inputs["p"], T)
    n = int(outside.sum())
    if n:
        where = ", ".join(str(k) for k in lines[outside][:SHOWN_ROWS])
        more = ", ..." if n > SHOWN_ROWS else ""
        print(
            f"warning: {n} of {outside.size} rows outside the envelope the fit's data covered "
            f"(load, pressure, temperature; [FIT_ENVELOPE] of {model.tir.path}): line(s) "
            f"{where}{more}; their forces are extrapolated",
            file=sys.stderr,
        )
    return f"{n} outside the fitted envelope"


def write_csv_atomic(path: Path, columns: Mapping[str, Array], overwrite: bool) -> None:
    """Write the columns to ``path`` atomically; floats with repr() precision."""
    names = list(columns)
    buf = io.StringIO(newline="")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in zip(*(columns[n] for n in names), strict=True):
        writer.writerow([repr(float(v)) for v in row])
    write_atomic(path, buf.getvalue(), overwrite=overwrite)


def run(args: argparse.Namespace) -> int:
    source = Path(args.input)
    target = Path(args.output)
    if target.exists() and not args.force:
        raise FileExistsError(f"{target}: output exists; use --force to overwrite it")
    if target.resolve() == source.resolve():
        raise ValueError(f"{target}: the output would replace the input file")
    if not target.parent.is_dir():
        raise FileNotFoundError(f"{target.parent}: output folder does not exist")
    model = load_model(args.tir, args.lenient)
    inputs, lines = read_inputs(source)
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
    outputs: dict[str, Array] = {name: getattr(out, name) for name in FORCE_CHANNELS}
    bad = non_finite_rows(outputs)
    if bad.any():
        raise ValueError(_refusal(source, bad, lines, outputs))
    write_csv_atomic(target, {**inputs, **outputs}, overwrite=args.force)
    note = "limits off" if args.no_limits else _saturation_note(model.params, inputs)
    outside = _envelope_warning(model, inputs, lines)
    print(f"wrote {target}: {inputs['Fz'].size} rows ({note}; {outside})")
    sys.stdout.flush()
    return 0
