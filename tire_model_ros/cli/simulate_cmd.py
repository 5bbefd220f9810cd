"""``tire-model simulate``: record a test programme on the virtual rig.

Writes BAG (rosbag2, MCAP) and ``<BAG>.truth.json`` beside it: the programme, the effects with
their true parameters, the omitted channels, the seed and the hidden states.

Example::

    tire-model simulate --tir tyre.tir --programme flat_trac -o run1 \\
        --effect heating --effect relaxation:sigma_alpha_m=0.4 --omit temperature --seed 3
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path

from tire_model_ros.cli.tirarg import add_lenient_argument, load_model

HELP = "record test programmes on the virtual rig"


def parse_spec(text: str, what: str) -> tuple[str, dict[str, str]]:
    """``NAME[:k=v,k=v]`` -> (NAME, {k: v}); ValueError naming the bad part."""
    name, _, rest = text.partition(":")
    name = name.strip()
    if not name:
        raise ValueError(f"{what} {text!r}: empty name")
    params: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        k, eq, v = item.partition("=")
        if not eq or not k.strip() or not v.strip():
            raise ValueError(f"{what} {text!r}: expected k=v, got {item!r}")
        params[k.strip()] = v.strip()
    return name, params


def _programme_value(v: str) -> bool | float:
    low = v.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    try:
        return float(v)
    except ValueError:
        raise ValueError(f"programme option value {v!r} is not a number or true/false") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..rig import EFFECTS, OMITTABLE, PROGRAMMES

    parser.add_argument("--tir", required=True, help="tyre property file the rig's tyre follows")
    parser.add_argument(
        "--programme",
        required=True,
        metavar="NAME[:k=v,...]",
        help=f"one of {', '.join(PROGRAMMES)}; options e.g. flat_trac:repeats=2,rate_scale=0.5",
    )
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="BAG",
        help="output bag (folder, or a lone .mcap file)",
    )
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME[:k=v,...]",
        help=f"switch an effect on (repeatable): {', '.join(EFFECTS)}; "
        "'noise:off' switches the default noise off (and 'sidewall:off' the one "
        "special_conditions switches on)",
    )
    parser.add_argument(
        "--omit",
        action="append",
        default=[],
        metavar="CHANNEL",
        help=f"leave a channel out of the bag (repeatable or comma list): {', '.join(OMITTABLE)}; "
        "'none' records every channel (default: the programme's choice, e.g. safe_envelope "
        "leaves the temperature out)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--rate", type=float, default=100.0, help="slip sample rate [Hz]")
    parser.add_argument("--force", action="store_true", help="overwrite BAG and its truth file")
    add_lenient_argument(parser)


def run(args: argparse.Namespace) -> int:
    from ..rig import simulate_session, truth_path, write_session

    bag = Path(args.output)
    if not args.force:
        for p in (bag, truth_path(bag)):
            if p.exists():
                raise FileExistsError(f"{p}: exists already (use --force)")
    if not Path(args.tir).is_file():
        raise FileNotFoundError(f"{args.tir}: no such .tir file")
    prog, popt = parse_spec(args.programme, "--programme")
    effects: dict[str, Mapping[str, str] | bool] = {}
    for spec in args.effect:
        if spec.strip().endswith(":off"):
            effects[spec.strip()[: -len(":off")]] = False
            continue
        name, params = parse_spec(spec, "--effect")
        effects[name] = params or True
    listed = [c.strip() for item in args.omit for c in item.split(",") if c.strip()]
    omit = [c for c in listed if c != "none"] if listed else None
    wheels, truth = simulate_session(
        load_model(args.tir, args.lenient),
        prog,
        effects=effects,
        omit=omit,
        seed=args.seed,
        rate_hz=args.rate,
        programme_options={k: _programme_value(v) for k, v in popt.items()},
    )
    _, tpath = write_session(bag, wheels, truth, overwrite=args.force)
    n = sum(len(w) for w in wheels)
    on = ", ".join(truth["effects"]) or "none"
    print(
        f"{bag}: {truth['programme']} {truth['duration_s']:.1f} s, {len(wheels)} wheel(s), "
        f"{n} samples; effects: {on}; omitted: {', '.join(truth['omitted']) or 'none'}"
    )
    print(f"{tpath}: truth")
    return 0
