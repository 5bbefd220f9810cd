"""``tire-model fit``: refit Magic Formula coefficients from one or more recordings.

Reads every wheel of every BAG, fits the coefficients of START stage by stage (Fx0, Fy0, Mz0,
combined slip, pressure terms, temperature terms; see ``tire_model_ros.fit.stages``), writes the
fitted model to OUT.tir (with its temperature section) and a report (markdown, JSON, PNG plots)
into the report folder. Existing files are never replaced without ``--force``.

With ``--extend SIM...`` the BAGs are a rig's recordings (the truth where they reach) and the
SIMs a simulation's (the virtual rig's special_conditions, an FE model's tables brought in with
``tire-model import --format csv``) that covers what the rig cannot: the seed paper's
extension (``tire_model_ros.fit.extend``). OUT.tir's ranges are then the fitted conditions and
the report folder holds ``extension.md`` with the operating envelope and the seed's figures.
Every fitted OUT.tir carries ``[FIT_ENVELOPE]``: the cells of load, pressure and temperature
its data covered (``tire_model_ros.model.envelope``), which ``eval`` and the node check.

OUT.tir and its report are written whole or not at all (``atomic.OutputSet``): staged in a
hidden folder ``.OUT.tir.partial`` beside OUT.tir, then renamed into place, the .tir first. A
run interrupted while staging leaves only that folder, which the next run removes; one
interrupted while renaming is finished by the next run. A fit with no stage fitted, or whose
model is not a tyre on its operating range (``model.check``), writes nothing; but when the
stages were tried and none beat the noise, the start model already explains the data and is
written as the result, with a note in the file and the report.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from tire_model_ros.cli.bagarg import add_salvage_argument, read_wheels
from tire_model_ros.cli.tirarg import add_lenient_argument, load_model

if TYPE_CHECKING:
    from tire_model_ros.atomic import OutputSet
    from tire_model_ros.fit import FitOptions
    from tire_model_ros.model import TireModel
    from tire_model_ros.recording.series import WheelSeries

HELP = "refit the model from recordings"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "bags",
        nargs="+",
        metavar="BAG",
        help="recording(s): rosbag2 folder or .mcap, or a measurement file imported on the fly "
        "(.mat/.dat TTC, .tdx TYDEX, .csv)",
    )
    parser.add_argument("--tir", required=True, metavar="START", help="start model (.tir)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.tir", help="fitted model")
    parser.add_argument(
        "--report", metavar="DIR", help="report folder (default: OUT_fit_report next to OUT.tir)"
    )
    parser.add_argument("--force", action="store_true", help="overwrite OUT.tir and the report")
    parser.add_argument(
        "--holdout-every",
        type=int,
        default=4,
        metavar="K",
        help="hold out every K-th sweep per condition for validation (default 4; 0 = none)",
    )
    parser.add_argument(
        "--warmup",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="drop the first SECONDS of every wheel (cold tyre)",
    )
    parser.add_argument(
        "--min-temperature",
        type=float,
        metavar="DEGC",
        help="drop samples whose recorded temperature is below DEGC",
    )
    parser.add_argument(
        "--stages",
        metavar="LIST",
        help="comma-separated stages to run (Fx0,Fy0,Mz0,combined,pressure,"
        "temperature; default all)",
    )
    parser.add_argument(
        "--wheel",
        action="append",
        metavar="PREFIX",
        help="fit only this wheel prefix (repeatable; default all wheels)",
    )
    parser.add_argument(
        "--extend",
        nargs="+",
        metavar="SIM",
        help="simulation recording(s) covering what the rig (the BAGs) cannot: low pressure, "
        "high load, cold and hot tyre (the seed paper's extension; see INTERFACE.md)",
    )
    parser.add_argument(
        "--rig-ambient",
        type=float,
        metavar="DEGC",
        help="with --extend: the rig's ambient, where its hidden tyre temperature starts "
        "(default NOMTEMP of START)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    add_lenient_argument(parser)
    add_salvage_argument(parser)


def default_report_dir(output: Path) -> Path:
    """``OUT_fit_report`` beside OUT.tir."""
    return output.with_name(f"{output.stem}_fit_report")


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.atomic import OutputSet
    from tire_model_ros.fit.extend_report import extension_paths
    from tire_model_ros.fit.report import report_paths

    out = Path(args.output)
    report_dir = Path(args.report) if args.report else default_report_dir(out)
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out.parent}: output folder does not exist")
    outputs = OutputSet([out, report_dir], overwrite=args.force)
    for note in outputs.recover():
        print(f"note: {note}", file=sys.stderr)
    # Refuse before any work: never replace a file that was not meant to be replaced.
    if out.exists() and not args.force:
        raise FileExistsError(f"{out}: exists; not overwriting it (use --force)")
    if not args.force:
        for p in extension_paths(report_dir) if args.extend else report_paths(report_dir):
            if p.exists():
                raise FileExistsError(f"{p}: exists; not overwriting the report (use --force)")
    for bag in [*args.bags, *(args.extend or ())]:  # cheap checks first (numba kernels load)
        if not Path(bag).exists() and not args.salvage:  # salvage may find its temp folder
            raise FileNotFoundError(f"{bag}: no such recording")
    if not Path(args.tir).is_file():
        raise FileNotFoundError(f"{args.tir}: no such .tir file")

    from tire_model_ros.fit import FitOptions, fit_recording, write_fit_report
    from tire_model_ros.fit.extend import envelope_of
    from tire_model_ros.model import write_tir
    from tire_model_ros.model.check import check_model
    from tire_model_ros.model.envelope import RIG

    start = load_model(args.tir, args.lenient)
    wheels = _read_wheels(args.bags, args.wheel, args.salvage)
    options = FitOptions(
        holdout_every=args.holdout_every,
        warmup_s=args.warmup,
        min_temperature=args.min_temperature,
        stages=[s.strip() for s in args.stages.split(",") if s.strip()] if args.stages else None,
        progress=False if args.quiet else None,
    )
    if options.progress is None:
        options.progress = True  # one line per stage; the live counter only on a TTY
    if args.extend:
        return _run_extend(args, start, wheels, options, outputs, out, report_dir)
    result = fit_recording(wheels, start, options)
    fitted = [st["stage"] for st in result.report["stages"] if st["status"] == "fitted"]
    fit_note: str | None = result.report.get("note")
    if not fitted and not fit_note:
        reasons = "; ".join(
            f"{st['stage']}: {st.get('reason', st['status'])}" for st in result.report["stages"]
        )
        raise ValueError(f"no stage could be fitted ({reasons}); nothing written")
    fault = check_model(result.model)
    if fault is not None:
        raise ValueError(f"the fitted model is not a tyre on its range: {fault}; nothing written")
    tir = result.model.tir
    if fit_note:  # the start model explains the data: it is the result, said in the file
        tir = dataclasses.replace(
            tir, path=None, preamble=(*tir.preamble, f"! tire-model fit: {fit_note}")
        )
        print(f"note: {fit_note}")
    report_dir.parent.mkdir(parents=True, exist_ok=True)
    T = [None if s.T is None else s.T for s in wheels]
    covered = envelope_of(start, wheels, RIG, T).filled()
    with outputs:
        write_tir(covered.into(tir), outputs.path(out))
        report_md = write_fit_report(result, outputs.path(report_dir), overwrite=True)
        outputs.commit()
    held = result.report["metrics"]["overall"]["heldout"]
    summary = ", ".join(
        f"{c} {held['before'][c]['rmse']:.4g} -> {held['after'][c]['rmse']:.4g}"
        for c in result.report["metrics"]["channels"]
        if held["after"][c]["n"] and held["before"][c]["rmse"] != held["after"][c]["rmse"]
    )
    print(f"wrote {out} (stages: {', '.join(fitted) or 'none; the start model'})")
    print(f"report {report_dir / report_md.name}")
    if summary:
        print(f"held-out rmse: {summary}")
    sys.stdout.flush()
    return 0


def _read_wheels(
    bags: Sequence[str], wanted: Sequence[str] | None, salvage: bool
) -> list[WheelSeries]:
    """Every wheel of the recordings (only the ``wanted`` prefixes when given)."""
    wheels = []
    for bag in bags:
        for prefix, series in read_wheels(bag, salvage=salvage).items():
            if wanted and prefix not in wanted:
                continue
            series.meta = {**(series.meta or {}), "bag": str(bag)}
            wheels.append(series)
    if not wheels:
        which = f" matching {', '.join(wanted)}" if wanted else ""
        raise ValueError(f"no wheel{which} in {', '.join(bags)}")
    return wheels


def _run_extend(
    args: argparse.Namespace,
    start: TireModel,
    rig: list[WheelSeries],
    options: FitOptions,
    outputs: OutputSet,
    out: Path,
    report_dir: Path,
) -> int:
    """``fit RIG... --extend SIM...``: fuse, check, write OUT.tir and the report."""
    from tire_model_ros.fit.extend import ExtendOptions, fit_extended
    from tire_model_ros.fit.extend_report import write_extension_report
    from tire_model_ros.model import write_tir
    from tire_model_ros.model.check import check_model

    sim = _read_wheels(args.extend, None, args.salvage)
    ext = ExtendOptions(fit=options, rig_ambient_C=args.rig_ambient, progress=not args.quiet)
    result = fit_extended(rig, sim, start, ext)
    fault = check_model(result.model)
    if fault is not None:
        raise ValueError(f"the fused model is not a tyre on its range: {fault}; nothing written")
    report_dir.parent.mkdir(parents=True, exist_ok=True)
    with outputs:
        write_tir(result.model.tir, outputs.path(out))
        report_md = write_extension_report(result, outputs.path(report_dir))
        outputs.commit()
    words = ", ".join(result.comparison.words)
    ranges = ", ".join(f"{k} {a:g} -> {b:g}" for k, (a, b) in result.ranges.items())
    print(f"wrote {out} (rig and simulation fused; the rig differs from it by: {words})")
    print(f"ranges: {ranges}")
    print(f"report {report_dir / report_md.name}")
    sys.stdout.flush()
    return 0
