"""tire-model: evaluate, simulate, replay, refit and diagnose Magic Formula tyre models.

Each subcommand lives in its own module.

A subcommand module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. Modules are imported only when their command runs, so
``tire-model --help`` stays fast and one broken command cannot break the others.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from tire_model_ros.ros import RosUnavailableError

COMMANDS: dict[str, tuple[str, str]] = {
    "eval": ("tire_model_ros.cli.eval_cmd", "evaluate the model on a CSV of inputs"),
    "info": ("tire_model_ros.cli.info_cmd", "wheels, topics, duration and ranges of a recording"),
    "simulate": ("tire_model_ros.cli.simulate_cmd", "record test programmes on the virtual rig"),
    "play": ("tire_model_ros.cli.play_cmd", "publish a recording's input topics with their timing"),
    "record": ("tire_model_ros.cli.record_cmd", "record the node's force topics to a new bag"),
    "fit": ("tire_model_ros.cli.fit_cmd", "refit the model from recordings"),
    "diagnose": ("tire_model_ros.cli.diagnose_cmd", "explain a model/recording mismatch"),
    "import": ("tire_model_ros.cli.import_cmd", "a TTC, TYDEX or CSV measurement as a recording"),
    "export": ("tire_model_ros.cli.export_cmd", "a recording as a TTC, TYDEX or CSV file"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tire-model", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module_name)
        # Arguments are added lazily in main() for the chosen command only.
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] not in COMMANDS:
        build_parser().parse_args(argv or ["--help"])  # prints help or the error, and exits
    module = importlib.import_module(COMMANDS[argv[0]][0])
    cmd = argparse.ArgumentParser(prog=f"tire-model {argv[0]}", description=COMMANDS[argv[0]][1])
    module.add_arguments(cmd)
    args = cmd.parse_args(argv[1:])
    try:
        return int(module.run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (OSError, ValueError, RosUnavailableError) as exc:  # user-facing, with their context
        print(f"tire-model {argv[0]}: error: {exc}", file=sys.stderr)
        return 1
