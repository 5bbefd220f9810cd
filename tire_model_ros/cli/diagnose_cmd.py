"""``tire-model diagnose BAG --tir FILE``: locate, name and model a model/recording mismatch."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tire_model_ros.atomic import write_atomic
from tire_model_ros.cli.bagarg import add_salvage_argument, read_wheels
from tire_model_ros.cli.tirarg import add_lenient_argument, load_model

if TYPE_CHECKING:
    from tire_model_ros.diagnosis import Diagnosis, WheelDiagnosis
    from tire_model_ros.model.tir import TirData

HELP = "locate, name and model a model/recording mismatch"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "bag",
        help="recording: rosbag2 folder, .mcap or .db3 file, or a measurement file imported "
        "on the fly (.mat/.dat TTC, .tdx TYDEX, .csv)",
    )
    parser.add_argument("--tir", required=True, help="the .tir property file to diagnose")
    parser.add_argument("--json", metavar="OUT", help="write the diagnosis JSON here")
    parser.add_argument("--report", metavar="DIR", help="write a report with plots into DIR")
    parser.add_argument(
        "--out-tir",
        metavar="FILE",
        help="write the improved .tir here (default: DIR/improved.tir with --report)",
    )
    parser.add_argument(
        "--wheel",
        action="append",
        metavar="PREFIX",
        help="diagnose only this wheel (repeatable; default: every wheel)",
    )
    parser.add_argument(
        "--reference",
        metavar="BAG2",
        help="a twin recording of the same session (e.g. the rig's noise-free one): the "
        "baseline and improved models are also scored on its held-out samples",
    )
    parser.add_argument(
        "--reference-json",
        metavar="OUT2",
        help="write the held-out RMSE against BAG2 here (the fit blocks of the JSON)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the sweep folds (default 0)")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    add_lenient_argument(parser)
    add_salvage_argument(parser)


def _check_free(path: str | os.PathLike[str] | None, force: bool) -> None:
    if path and Path(path).exists() and not force:
        raise FileExistsError(f"{path}: exists; not overwriting it (use --force)")


def write_json_atomic(
    obj: dict[str, Any], path: str | os.PathLike[str], overwrite: bool = False
) -> None:
    """Write ``obj`` as JSON (no NaN: INTERFACE.md JSON is strict), atomically."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(obj, indent=2, allow_nan=False) + "\n", overwrite=overwrite)


def effects_path(tir_path: str | os.PathLike[str]) -> Path:
    """The effects file written beside an improved .tir: ``improved.tir`` ->
    ``improved.effects.json``."""
    return Path(tir_path).with_suffix(".effects.json")


def improved_tir(wd: WheelDiagnosis, source_tir: TirData) -> TirData:
    """TirData of one wheel's improved model: fitted coefficients, effect parameters as
    comments."""
    notes = [f"! tire-model diagnose: improved model of {wd.prefix} (fitted coefficients below)."]
    for e in wd.effects:
        if e.name == "none":
            continue
        params = ", ".join(f"{k} = {v:.6g}" for k, v in e.parameters.items())
        notes.append(f"! effect {e.name}{' (concealed)' if e.concealed else ''}: {params}")
    return dataclasses.replace(
        source_tir,
        path=None,
        params=dict(wd.improved_model.params),
        preamble=(*source_tir.preamble, *notes),
    )


def tir_paths(diag: Diagnosis, out_tir: str | os.PathLike[str]) -> dict[str, Path]:
    """Where each wheel's improved .tir goes: OUT itself for one wheel; for several,
    ``OUT.<wheel>.tir`` each (``improved.tir`` -> ``improved.car_fl.tir``)."""
    out = Path(out_tir)
    if len(diag.wheels) == 1:
        return {next(iter(diag.wheels)): out}
    return {p: out.with_suffix(f".{_slug(p)}.tir") for p in diag.wheels}


def _slug(prefix: str) -> str:
    return prefix.strip("/").replace("/", "_") or "wheel"


def node_params(diag: Diagnosis, tirs: dict[str, Path], effects: Path) -> str:
    """A node parameter file that runs the improved model of every wheel (several wheels)."""
    lines = ["tire_model_node:", "  ros__parameters:", f"    wheels: {list(diag.wheels)}"]
    lines += [
        f"    tir_file: {tirs[next(iter(diag.wheels))].name}",
        f"    effects_file: {effects.name}",
    ]
    for p, path in tirs.items():
        key = p.strip("/").split("/")
        lines += [f"    {'.'.join(key)}.tir_file: {path.name}"]
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    from tire_model_ros.diagnosis import diagnose
    from tire_model_ros.diagnosis.report import heldout_warnings, look_alike_summary, told_apart
    from tire_model_ros.model import write_tir

    out_tir = args.out_tir or (str(Path(args.report) / "improved.tir") if args.report else None)
    if bool(args.reference) != bool(args.reference_json):
        raise ValueError("--reference and --reference-json go together")
    if args.reference and not Path(args.reference).exists():  # before the minutes of diagnosis
        raise FileNotFoundError(f"{args.reference}: no such file or directory")
    out_effects = effects_path(out_tir) if out_tir else None
    for path in (args.json, args.out_tir, args.reference_json, args.out_tir and out_effects):
        _check_free(path, args.force)
    if (
        args.report
        and Path(args.report).exists()
        and any(Path(args.report).iterdir())
        and not args.force
    ):
        raise FileExistsError(f"{args.report}: exists and is not empty (use --force)")
    model = load_model(args.tir, args.lenient)
    wheels = read_wheels(args.bag, args.wheel, args.salvage)
    t0, c0 = time.perf_counter(), time.process_time()
    diag = diagnose(list(wheels.values()), model, seed=args.seed)
    elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0

    print(f"diagnosis of {args.bag} against {args.tir} ({elapsed:.1f} s, {cpu:.1f} s CPU):")
    for i, e in enumerate(diag.effects, 1):
        tag = " (concealed)" if e.concealed else ""
        print(f"  {i}. {e.name}{tag} on {e.channel}")
        print(f"     where: {e.where}")
        print(f"     evidence: {e.evidence}")
    if diag.look_alikes:
        print(f"  {look_alike_summary(diag.look_alikes)}; what would tell them apart:")
        for line in told_apart(list(diag.look_alikes), [e.name for e in diag.effects]):
            print(f"    {line}")
    for ch in diag.fit["heldout_baseline"]:
        a = diag.fit["heldout_baseline"][ch]["rmse"]
        b = diag.fit["heldout_improved"][ch]["rmse"]
        if a is not None and b is not None:
            unit = "N m" if ch == "Mz" else "N"
            print(f"  held-out {ch} RMSE: {a:.1f} -> {b:.1f} {unit}")
    for prefix, names in diag.inputs_dropped.items():
        print(f"  {prefix}: {', '.join(names)} not finite on any sample: taken as not recorded")
    for prefix, gaps in diag.inputs_bridged.items():
        counts = ", ".join(f"{k} {n}" for k, n in gaps.items())
        print(f"  {prefix}: inputs not finite on samples ({counts}): bridged, not scored")
    for warning in heldout_warnings(diag.fit):
        print(f"  {warning}")
    if args.json:
        write_json_atomic(diag.to_json(), args.json, overwrite=args.force)
        print(f"wrote {args.json}")
    if args.reference:
        twin = read_wheels(args.reference, args.wheel, args.salvage)
        ref = diag.score_reference(list(twin.values()))
        for ch in ref["heldout_baseline"]:
            a = ref["heldout_baseline"][ch]["rmse"]
            b = ref["heldout_improved"][ch]["rmse"]
            if a is not None and b is not None:
                print(f"  held-out {ch} RMSE against {args.reference}: {a:.1f} -> {b:.1f}")
        for ch, v in ref["heldout_floor"].items():
            if v["rmse"] is not None:
                print(
                    f"  held-out {ch} RMSE floor (the true physics on this recording's "
                    f"noise): {v['rmse']:.1f}"
                )
        write_json_atomic(ref, args.reference_json, overwrite=args.force)
        print(f"wrote {args.reference_json}")
    if args.report:
        from tire_model_ros.diagnosis.report import write_report

        path = write_report(diag, wheels, args.report, overwrite=args.force, source=str(args.bag))
        print(f"wrote {path}")
    if out_tir:
        again = args.force or bool(args.report and not args.out_tir)
        tirs = tir_paths(diag, out_tir)
        for prefix, path in tirs.items():
            write_tir(improved_tir(diag.wheels[prefix], model.tir), path, overwrite=again)
            print(f"wrote {path}")
        effects = diag.node_effects(Path(out_tir).name)
        effects_file = effects_path(out_tir)
        write_atomic(effects_file, effects.to_json(), overwrite=again)
        if len(tirs) > 1:
            yaml_path = Path(out_tir).with_suffix(".node.yaml")
            write_atomic(yaml_path, node_params(diag, tirs, effects_file), overwrite=again)
            print(f"wrote {yaml_path} (tire-model-node --ros-args --params-file {yaml_path})")
        print(
            f"wrote {effects_file} (hidden states for the node's effects_file"
            + (f"; not carried: {'; '.join(effects.not_carried)})" if effects.not_carried else ")")
        )
    sys.stdout.flush()
    return 0
