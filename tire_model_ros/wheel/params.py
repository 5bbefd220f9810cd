"""Parameter names, ranges and .tir path resolution of the node (no ROS import).

Naming (also documented in the node's module docstring and in ``config/car4.yaml``):

- A wheel prefix (topic namespace) maps to a parameter key by dropping the leading ``/`` and
  turning every other ``/`` into ``.``: ``/car/rl`` -> ``car.rl``, ``wheel`` -> ``wheel``.
- ``tir_file`` and the bare coefficient names (``PDY1``, ``LMUY``, ...) belong to the shared
  model that every wheel uses unless it has a file of its own.
- ``<wheelkey>.tir_file`` (default ``""`` = use the shared model) gives that wheel its own
  model; its coefficients are then ``<wheelkey>.<NAME>`` (``car.rl.PDY1``).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from tire_model_ros.model import params as table

PACKAGE = "tire_model_ros"

#: Parameters of the node itself; a wheel key must not collide with them.
GLOBAL_PARAMS = (
    "wheels",
    "tir_file",
    "effects_file",
    "limits",
    "pressure_is_absolute",
    "ambient_pressure",
    "missing_load",
    "timeout",
    "align",
    "diagnostics_period",
    "qos_depth",
    "input_reliability",
    "input_history",
    "output_reliability",
    "lenient",
    "rt_priority",
    "cpus",
    "use_sim_time",
)
#: Default staleness timeouts [s]; 0 disables the check (value held for ever).
DEFAULT_TIMEOUTS = {"load": 1.0, "pressure": 10.0, "temperature": 10.0, "velocity": 1.0}
MISSING_LOAD_POLICIES = ("nominal", "skip")
#: How long [s, ROS clock] a slip may wait for its inputs' stamps to catch up (``align.wait``;
#: 0 = answer on arrival, the default: a simulator or a control loop gets its forces at once,
#: and an input slower than the slips, pressure at 1 Hz, would hold each slip until its next
#: value). A replay under load sets it (``make demo``: 30 s). It is also how long an input may
#: stay silent and still be waited for: a reliable topic that loses a sample delivers nothing
#: after it until the writer's next heartbeat repairs it (every 3 s in Fast DDS by default).
#: ``make demo``'s replay beside two CPU hogs: slips waited up to 3.1 s for their load, and the
#: load topic went silent for up to 14.6 s while slips kept coming (5, 12 and 15 s of bound
#: were needed in three runs).
DEFAULT_ALIGN_WAIT = 0.0
REPLAY_ALIGN_WAIT = 30.0  # what make demo's replay beside two CPU hogs needed, with margin
MAX_ALIGN_WAIT = 300.0

_KEY_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(\.[A-Za-z][A-Za-z0-9_]*)*$")


def wheel_key(prefix: str) -> str:
    """Parameter key of a wheel prefix: ``/car/rl`` -> ``car.rl``.

    Raises ValueError when the prefix cannot be a ROS topic namespace and parameter key.
    """
    key = prefix.strip("/").replace("/", ".")
    if not _KEY_RE.match(key):
        raise ValueError(
            f"wheel prefix {prefix!r}: use letters, digits and '_' between '/' "
            "(each part starting with a letter), e.g. '/car/fl'"
        )
    if key.split(".")[0] in GLOBAL_PARAMS:
        raise ValueError(f"wheel prefix {prefix!r} collides with the node parameter {key!r}")
    return key


def wheel_keys(prefixes: Iterable[str]) -> dict[str, str]:
    """Prefix -> key for every wheel; raises ValueError on duplicates or bad names."""
    out: dict[str, str] = {}
    for prefix in prefixes:
        key = wheel_key(prefix)
        if key in out.values():
            raise ValueError(f"wheel prefix {prefix!r} given twice (key {key!r})")
        out[prefix] = key
    if not out:
        raise ValueError("parameter 'wheels' is empty: give at least one wheel prefix")
    return out


def coefficient_range(name: str) -> tuple[float, float, bool] | None:
    """(minimum, maximum, strict_min) that the physics sets for a coefficient, or None.

    From the coefficient table of the model (``tire_model_ros.model.params``); an open side
    is +-inf.
    """
    spec = table.PARAMETERS.get(name.upper())
    if spec is None or (spec.minimum is None and spec.maximum is None):
        return None
    lo = -math.inf if spec.minimum is None else spec.minimum
    hi = math.inf if spec.maximum is None else spec.maximum
    return lo, hi, spec.strict_min


def coefficient_description(name: str) -> str:
    """One-line description with units, from the model's coefficient table."""
    try:
        return table.describe(name)
    except KeyError:
        return f"Magic Formula coefficient {name} of the .tir file"


def coefficient_value(name: str, value: object) -> float:
    """Check a coefficient value as set through ROS: a finite number inside its range.

    ``name`` may carry a wheel key (``car.rl.PDY1``); the range is the coefficient's.
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name}: expected a number, got {type(value).__name__} {value!r}")
    x = float(value)
    problem = table.check_value(name.rsplit(".", 1)[-1], x)
    if problem is not None:
        raise ValueError(f"{name}: {problem}" if "." in name else problem)
    return x


def config_dirs() -> list[Path]:
    """Where the package's config/ may be: colcon share dir, source tree, venv share dir."""
    dirs: list[Path] = []
    try:
        from ament_index_python.packages import (
            PackageNotFoundError,
            get_package_share_directory,
        )

        # Not installed in an ament prefix, or AMENT_PREFIX_PATH unset: skip.
        with contextlib.suppress(PackageNotFoundError, LookupError, ValueError, OSError):
            dirs.append(Path(get_package_share_directory(PACKAGE)) / "config")
    except ImportError:
        pass
    dirs.append(Path(__file__).resolve().parents[2] / "config")  # source tree / editable
    dirs.append(Path(sys.prefix) / "share" / PACKAGE / "config")
    return dirs


def default_tir_path() -> str:
    """The package's ``config/default.tir``; "" when no install of it is found."""
    for d in config_dirs():
        candidate = d / "default.tir"
        if candidate.is_file():
            return str(candidate)
    return ""


def resolve_tir_path(value: str) -> Path:
    """A .tir path as given (absolute, or relative to the working directory), else relative to
    the package's config directory (so a YAML file may say ``tir_file: default.tir``)."""
    if not value:
        raise ValueError("tir_file is empty and no config/default.tir is installed")
    path = Path(os.path.expanduser(value))
    if path.is_file() or path.is_absolute():
        return path.resolve() if path.is_file() else path
    for d in config_dirs():
        if (d / path).is_file():
            return (d / path).resolve()
    return path


@dataclass(frozen=True)
class ParamName:
    """What a parameter name addresses: ``kind`` is 'file', 'coef' or 'node'.

    ``slot`` is "" for the shared model or the wheel key for a wheel's own model.
    """

    kind: str
    slot: str
    key: str


def classify(name: str, keys: Iterable[str]) -> ParamName:
    """Split a parameter name into (kind, slot, key) given the wheel keys."""
    if name == "tir_file":
        return ParamName("file", "", "tir_file")
    for wk in sorted(keys, key=len, reverse=True):  # longest first: 'car.rl' before 'car'
        if name.startswith(wk + "."):
            rest = name[len(wk) + 1 :]
            return ParamName("file" if rest == "tir_file" else "coef", wk, rest)
    if name.split(".")[0] in GLOBAL_PARAMS:
        return ParamName("node", "", name)
    return ParamName("coef", "", name)
