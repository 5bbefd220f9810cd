"""Is a coefficient set a tyre? The model evaluated on a grid over its own operating range.

``read_tir`` refuses a file whose model fails :func:`check_model`, and the node refuses a
coefficient change that does. The grid spans the ranges the file gives (loads FZMIN..FZMAX and
0, slips KPUMIN..KPUMAX, ALPMIN..ALPMAX, inclinations CAMMIN..CAMMAX, pressures
PRESMIN..PRESMAX), speeds -150, -LONGVL, 0, VXLOW/2, LONGVL, 3 LONGVL, 150 m/s (a .tir gives no
speed range: +-``SPEED_SANITY_M_S`` is the node's) and temperatures TEMPMIN,
NOMTEMP, TEMPMAX (the file's ``[TEMPERATURE_RANGE]``, else the table's sanity range -50..150
degC), with the limits on (saturation, low-speed model) and off (the plain equations);
``operating_grid`` says how. Every output of ``evaluate(full=False)`` (what ``eval``
and the node give: forces, moments, slip stiffnesses, friction coefficients, trail) must be
finite there, and the forces and moments those of a tyre on the ranges the file declares (at
NOMTEMP: the temperature terms are judged by finiteness only, see ``operating_grid``):

    |Fx|, |Fy| <= 10 Fz*          (a friction coefficient of 10 is no tyre)
    |Mx|, |My|, |Mz| <= 10 Fz* R0

with Fz* = max(Fz, FZMIN with the limits on, FNOMIN/1000) [N] and R0 = UNLOADED_RADIUS [m]. The
reference files stay below 3.5 and 0.6 of these (FSAE_Defaults' Fy at low load is the highest).

The radii, carcass stiffnesses and relaxation lengths of ``full=True`` are not checked: an MF 5.x
file without relaxation terms (PTY1 = PTY2 = 0, the Chrono FED tyre) has sigmay = 0/0 at zero
load, and they enter no force. A grid cannot prove the model finite between its points;
``tire-model eval`` therefore also checks every row it writes.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .params import PARAMETERS

if TYPE_CHECKING:
    from .mf import MFOutput, TireModel

__all__ = [
    "MAX_FORCE_PER_LOAD",
    "MAX_MOMENT_PER_LOAD_RADIUS",
    "SPEED_SANITY_M_S",
    "ModelFault",
    "check_model",
    "operating_grid",
    "saturated_rows",
]

Array = npt.NDArray[np.float64]

MAX_FORCE_PER_LOAD = 10.0  # |Fx|, |Fy| / Fz* [-]
#: |Vx| [m/s] beyond which a speed is no road tyre's (540 km/h, above every speed rating; the
#: node saturates there, a .tir gives no speed range).
SPEED_SANITY_M_S = 150.0
MAX_MOMENT_PER_LOAD_RADIUS = 10.0  # |Mx|, |My|, |Mz| / (Fz* R0) [-]
_FORCES = ("Fx", "Fy")
_MOMENTS = ("Mx", "My", "Mz")
_INPUTS = ("Fz", "kappa", "alpha", "gamma", "Vx", "p", "T")
_MAX_PROBES = 32  # failing points re-evaluated per coefficient when looking for the cause


@dataclass(frozen=True)
class ModelFault:
    """Where a coefficient set stops being a tyre.

    Attributes
    ----------
    output : the output that fails, e.g. ``"Mx"``.
    reason : what is wrong with it there, e.g. ``"inf"``, ``"|Fy| = 3e+15 N, 8e+11 x Fz*"``.
    point : the operating point (Fz [N], kappa, alpha [rad], gamma [rad], Vx [m/s], p [Pa],
        T [degC], limits).
    causes : coefficients each of which, put back to its default alone, makes every failing
        point pass (empty when no single one does).
    n_points : how many grid points fail.
    """

    output: str
    reason: str
    point: Mapping[str, float]
    causes: tuple[str, ...]
    n_points: int

    def __str__(self) -> str:
        where = ", ".join(f"{k}={v:.4g}" for k, v in self.point.items())
        text = f"{self.output} is {self.reason} at {where} ({self.n_points} grid points fail)"
        if self.causes:
            text += f"; with its default {' or '.join(self.causes)} would pass"
        return text


def _span(lo: float, hi: float, n: int) -> Array:
    """n points over [lo, hi] and 0 when it lies inside (the slip-free state)."""
    points = np.linspace(lo, hi, n)
    if lo < 0.0 < hi:
        points = np.append(points, 0.0)
    return np.unique(points)


def operating_grid(params: Mapping[str, float]) -> dict[str, Array]:
    """The check's grid: inputs of :meth:`TireModel.evaluate` as flat arrays of one length.

    Three products: loads x slips x inclinations x speeds at the nominal pressure and
    temperature; loads x slips x pressures, and loads x slips x temperatures, upright at LONGVL.
    ``bounded`` is 1 where the tyre bounds apply: on the ranges the file declares. At
    temperatures other than NOMTEMP only finiteness is asked: most files give no temperature
    range (the sanity range stands in) and the temperature terms are polynomials fitted over a
    session's span, not beyond it.
    """
    P = params
    fz0 = P["FNOMIN"]
    loads = np.unique([0.0, 0.01 * fz0, P["FZMIN"], fz0, 0.5 * (fz0 + P["FZMAX"]), P["FZMAX"]])
    loads = loads[(loads >= 0.0) & (loads <= max(P["FZMAX"], fz0))]
    kappa = _span(P["KPUMIN"], P["KPUMAX"], 7)
    alpha = _span(P["ALPMIN"], P["ALPMAX"], 7)
    gamma = _span(P["CAMMIN"], P["CAMMAX"], 2)
    v0 = P["LONGVL"]
    vmax = SPEED_SANITY_M_S
    speeds = np.unique([-vmax, -v0, 0.0, 0.5 * P["VXLOW"], v0, 3.0 * v0, vmax])
    p0 = P["INFLPRES"] if P.get("INFLPRES", 0.0) > 0.0 else P["NOMPRES"]
    pressures = np.unique([P["PRESMIN"], P["NOMPRES"], P["PRESMAX"]])
    t0 = P["NOMTEMP"]
    temperatures = np.array([P["TEMPMIN"], P["TEMPMAX"]])
    ks, als = kappa[::2], alpha[::2]
    blocks = [
        (np.meshgrid(loads, kappa, alpha, gamma, speeds, [p0], [t0], indexing="ij"), 1.0),
        (np.meshgrid(loads, ks, als, [0.0], [v0], pressures, [t0], indexing="ij"), 1.0),
        (np.meshgrid(loads, ks, als, [0.0], [v0], [p0], temperatures, indexing="ij"), 0.0),
    ]
    grid = {
        name: np.concatenate([block[k].ravel() for block, _ in blocks])
        for k, name in enumerate(_INPUTS)
    }
    grid["bounded"] = np.concatenate([np.full(block[0].size, flag) for block, flag in blocks])
    return grid


def _failures(
    model: TireModel, grid: Mapping[str, Array], limits: bool
) -> tuple[str, str, npt.NDArray[np.intp]] | None:
    """(output, reason of its first failing point, failing indices) of the first failing output."""
    out = model.evaluate(
        grid["Fz"], grid["kappa"], grid["alpha"], grid["gamma"], grid["Vx"], grid["p"],
        grid["T"], limits=limits, full=False,
    )  # fmt: skip
    P = model.params
    floor = np.maximum(grid["Fz"], 1e-3 * P["FNOMIN"])
    if limits:
        floor = np.maximum(floor, P["FZMIN"])
    bounds = {n: MAX_FORCE_PER_LOAD * floor for n in _FORCES}
    bounds |= {n: MAX_MOMENT_PER_LOAD_RADIUS * floor * P["UNLOADED_RADIUS"] for n in _MOMENTS}
    for field in dataclasses.fields(out):
        values = getattr(out, field.name)
        if values is None:
            continue
        bad = ~np.isfinite(values)
        bound = bounds.get(field.name)
        if bound is not None:
            bad |= (grid["bounded"] > 0.0) & (np.abs(values) > bound)
        if bad.any():
            where = np.flatnonzero(bad)
            return field.name, _reason(field.name, out, where[0], bound), where
    return None


def _reason(name: str, out: MFOutput, i: int, bound: Array | None) -> str:
    value = float(getattr(out, name)[i])
    if not math.isfinite(value) or bound is None:
        return repr(value)
    unit = "N" if name in _FORCES else "N m"
    return f"{value:.4g} {unit}, beyond the bound {float(bound[i]):.4g} {unit} of a tyre"


def _causes(
    model: TireModel, grid: Mapping[str, Array], limits: bool, where: npt.NDArray[np.intp]
) -> tuple[str, ...]:
    """Coefficients of the file whose default alone makes the failing points pass."""
    from .mf import TireModel

    probe = {k: v[where[:_MAX_PROBES]] for k, v in grid.items()}
    tir = model.tir
    found = []
    for key in sorted(tir.given):
        spec = PARAMETERS.get(key)
        if spec is None or tir.params[key] == spec.default:
            continue
        trial = TireModel(dataclasses.replace(tir, params={**tir.params, key: spec.default}))
        if _failures(trial, probe, limits) is None:
            found.append(key)
    return tuple(found)


def check_model(model: TireModel) -> ModelFault | None:
    """The first way the model fails on its operating grid, or None when it is a tyre there.

    Costs about 10 ms (two evaluations of some 5000 points); when it fails, finding the
    coefficients that cause it re-evaluates the failing points once per coefficient of the file.
    """
    grid = operating_grid(model.params)
    for limits in (True, False):
        failure = _failures(model, grid, limits)
        if failure is None:
            continue
        output, reason, where = failure
        point = {k: float(grid[k][where[0]]) for k in _INPUTS}
        point["limits"] = float(limits)
        return ModelFault(output, reason, point, _causes(model, grid, limits, where), where.size)
    return None


def saturated_rows(params: Mapping[str, float], inputs: Mapping[str, Array]) -> dict[str, int]:
    """Rows whose inputs ``evaluate(limits=True)`` changes: outside the file's ranges, a
    negative load (read as 0), or a speed at or below VXLOW (the low-speed model).

    ``inputs`` holds ``Fz, kappa, alpha, gamma, Vx, p`` arrays [N, -, rad, rad, m/s, Pa] and
    may hold ``T`` [degC] (saturated to TEMPMIN..TEMPMAX).
    """
    P = params
    ranges = {
        "kappa": (P["KPUMIN"], P["KPUMAX"]),
        "alpha": (P["ALPMIN"], P["ALPMAX"]),
        "gamma": (P["CAMMIN"], P["CAMMAX"]),
        "p": (P["PRESMIN"], P["PRESMAX"]),
    }
    if "T" in inputs:
        ranges["T"] = (P["TEMPMIN"], P["TEMPMAX"])
    counts = {"Fz": int(np.count_nonzero((inputs["Fz"] < 0.0) | (inputs["Fz"] > P["FZMAX"])))}
    for name, (lo, hi) in ranges.items():
        counts[name] = int(np.count_nonzero((inputs[name] < lo) | (inputs[name] > hi)))
    counts["Vx (low-speed model)"] = int(np.count_nonzero(np.abs(inputs["Vx"]) <= P["VXLOW"]))
    return counts
