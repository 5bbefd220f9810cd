"""Units of measurement files, converted to the project's SI units (INTERFACE.md).

Every quantity has its SI unit (time s, angle rad, slip -, force N, moment N m, pressure Pa
gauge, speed m/s, temperature degC as the topics carry it) and a table of the spellings that
rigs and tools write, each with ``si = value * scale + offset``. Spellings are compared after
:func:`normalise` (lower case, no blanks, brackets or dots, ``°`` read as ``deg``), so
``deg C``, ``°C`` and ``degC`` are one unit. A unit that is not in the quantity's table is an
error: a wrong or unknown unit never passes unconverted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Floats = npt.NDArray[np.float64]

LBF_N = 4.4482216152605  # pound-force [N]
FT_M = 0.3048
IN_M = 0.0254
PSI_PA = LBF_N / IN_M**2  # 6894.757... Pa


@dataclass(frozen=True)
class Scale:
    """``si = value * factor + offset``."""

    factor: float
    offset: float = 0.0


# quantity -> (SI unit as printed, {normalised spelling: Scale})
QUANTITIES: dict[str, tuple[str, dict[str, Scale]]] = {
    "time": (
        "s",
        {"s": Scale(1.0), "sec": Scale(1.0), "second": Scale(1.0), "seconds": Scale(1.0),
         "ms": Scale(1e-3), "min": Scale(60.0)},
    ),
    "angle": (
        "rad",
        {"rad": Scale(1.0), "radian": Scale(1.0), "radians": Scale(1.0),
         "deg": Scale(math.pi / 180.0), "degree": Scale(math.pi / 180.0),
         "degrees": Scale(math.pi / 180.0), "mrad": Scale(1e-3)},
    ),
    "slip": (
        "-",
        {"-": Scale(1.0), "": Scale(1.0), "none": Scale(1.0), "1": Scale(1.0),
         "ratio": Scale(1.0), "%": Scale(0.01), "percent": Scale(0.01)},
    ),
    "force": (
        "N",
        {"n": Scale(1.0), "kn": Scale(1e3), "dan": Scale(10.0), "lb": Scale(LBF_N),
         "lbf": Scale(LBF_N), "lbs": Scale(LBF_N), "kgf": Scale(9.80665)},
    ),
    "moment": (
        "N m",
        {"nm": Scale(1.0), "n-m": Scale(1.0), "m-n": Scale(1.0), "knm": Scale(1e3),
         "kn-m": Scale(1e3), "ft-lb": Scale(LBF_N * FT_M), "lb-ft": Scale(LBF_N * FT_M),
         "ftlb": Scale(LBF_N * FT_M), "lbft": Scale(LBF_N * FT_M),
         "ft-lbf": Scale(LBF_N * FT_M), "lbf-ft": Scale(LBF_N * FT_M),
         "in-lb": Scale(LBF_N * IN_M), "lb-in": Scale(LBF_N * IN_M),
         "in-lbf": Scale(LBF_N * IN_M), "lbf-in": Scale(LBF_N * IN_M)},
    ),
    "pressure": (
        "Pa",
        {"pa": Scale(1.0), "kpa": Scale(1e3), "mpa": Scale(1e6), "bar": Scale(1e5),
         "mbar": Scale(100.0), "psi": Scale(PSI_PA), "psig": Scale(PSI_PA),
         "kpag": Scale(1e3), "barg": Scale(1e5)},
    ),
    "speed": (
        "m/s",
        {"m/s": Scale(1.0), "mps": Scale(1.0), "km/h": Scale(1 / 3.6), "kph": Scale(1 / 3.6),
         "kmh": Scale(1 / 3.6), "km/hr": Scale(1 / 3.6), "mph": Scale(0.44704),
         "ft/s": Scale(FT_M)},
    ),
    "temperature": (
        "degC",
        {"degc": Scale(1.0), "c": Scale(1.0), "celsius": Scale(1.0),
         "degf": Scale(5 / 9, -32 * 5 / 9), "f": Scale(5 / 9, -32 * 5 / 9),
         "fahrenheit": Scale(5 / 9, -32 * 5 / 9), "k": Scale(1.0, -273.15),
         "kelvin": Scale(1.0, -273.15)},
    ),
}  # fmt: skip


class UnitError(ValueError):
    """A unit that is unknown, or not a unit of the channel's quantity."""


def normalise(unit: str) -> str:
    """The comparable spelling of a unit: ``'[deg C]'`` -> ``'degc'``, ``'N.m'`` -> ``'n-m'``."""
    u = unit.strip().lower().replace("°", "deg").replace("·", "-").replace("*", "-")
    for ch in "[]() ":
        u = u.replace(ch, "")
    return u.replace(".", "-")


def scale_of(unit: str, quantity: str) -> Scale:
    """The conversion of ``unit`` to SI for ``quantity``.

    Raises
    ------
    UnitError
        The unit is unknown or of another quantity (its text names the known spellings).
    """
    si, table = QUANTITIES[quantity]
    found = table.get(normalise(unit))
    if found is None:
        known = ", ".join(k for k in table if k) or si
        raise UnitError(f"unknown unit {unit!r} for the {quantity} (known: {known}; SI: {si})")
    return found


def to_si(values: Floats, unit: str, quantity: str) -> Floats:
    """``values`` in ``unit`` converted to the SI unit of ``quantity``."""
    s = scale_of(unit, quantity)
    out: Floats = values * s.factor + s.offset
    return out


def from_si(values: Floats, unit: str, quantity: str) -> Floats:
    """SI ``values`` of ``quantity`` expressed in ``unit`` (the exporters' direction)."""
    s = scale_of(unit, quantity)
    out: Floats = (values - s.offset) / s.factor
    return out
