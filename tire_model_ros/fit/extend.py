"""The seed paper's extension: a rig's recordings fused with a simulation beyond the rig.

``tire-model fit RIG... --tir START -o OUT.tir --extend SIM...`` (INTERFACE.md). A Flat-Trac
cannot safely test a tyre at low pressure, high load or a cold or hot tyre; a simulation (the
virtual rig's ``special_conditions``, an FE model's tables imported with ``import``) can, but it
is not the tyre: an FE model is isothermal while the tyre on the rig heats as it runs. So:

1. the simulation is fitted alone (:func:`fit_recording`); where its lateral force drops at
   high deflection (``sidewall_contact``, :mod:`.sidewall`) those samples are left out of the
   lateral fit, which is then repeated;
2. the rig is diagnosed against the simulation's model (:func:`diagnose`): the words say how
   the two differ where both reach. A concealed ``temperature`` is corrected: the rig's hidden
   temperature takes the shape the diagnosis inferred, its scale fitted on the rig with the
   temperature terms the simulation's known set temperatures gave (:func:`heating_scale`).
   Together with it a friction level of the rig's own is fitted (how far the simulation's
   friction is off); the diagnosis' other words are reported, not corrected;
3. the final fit is the rig's (with that temperature): its levels (friction, stiffness at
   the nominal load, shifts, aligning moment, combined slip: ``LEVELS``) refitted with the
   simulation's shapes and trends held (:func:`trend_terms`). The rig is the truth where it
   has data; beyond it the model is the rig's levels with the simulation's trends (the
   simulation's forces inform the trends only, through step 1);
4. OUT.tir's ranges (PRESMIN/PRESMAX, FZMIN/FZMAX, TEMPMIN/TEMPMAX) are the fitted data's and
   its ``[FIT_ENVELOPE]`` says which source informed which cells (:mod:`..model.envelope`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from tire_model_ros.model import TireModel
from tire_model_ros.model.envelope import RIG, SIMULATION, Envelope
from tire_model_ros.recording.series import WheelSeries

from .core import evaluate_on, nominal_inputs, stack_inputs
from .sidewall import SidewallFit, find_sidewall
from .stages import STAGES, FitOptions, FitResult, fit_recording
from .sweeps import noise_sigma

if TYPE_CHECKING:
    from tire_model_ros.diagnosis import Diagnosis

F64 = npt.NDArray[np.float64]
Bools = npt.NDArray[np.bool_]

FORCES = ("Fx", "Fy", "Mx", "My", "Mz")
SWEPT_KAPPA = 0.005  # a sample is on a sweep (counts for the envelope) beyond these slips
SWEPT_ALPHA_RAD = math.radians(0.5)
HEATING_SCALE_MAX = 10.0  # of the diagnosis' temperature convention
HEATING_FIT_ROWS = 20_000
# Cells of the envelope: load [FNOMIN], pressure [Pa], temperature [K].
FZ_STEP_FNOMIN = 0.1
P_STEP_PA = 20_000.0
T_STEP_K = 5.0
ENVELOPE_MIN_SAMPLES = 50  # samples on a sweep in a cell for it to count (0.5 s at 100 Hz)
# What the rig's recordings set where both reach (the seed paper: an FE model predicts the
# trends and the peak's place well; its friction level and stiffness are what a test corrects):
# friction and slip stiffness at the nominal load, the shifts (ply-steer, conicity, rolling
# resistance), the aligning moment's base and the combined-slip terms (a rig's own).
LEVELS = frozenset(
    {"PDX1", "PHX1", "PVX1", "PDY1", "PHY1", "PVY1"}
    | {k for st in STAGES if st.name in ("Mz0", "combined") for k in st.base}
)


@dataclass
class ExtendOptions:
    """Knobs of :func:`fit_extended` beyond those of the staged fit."""

    fit: FitOptions = field(default_factory=FitOptions)
    rig_ambient_C: float | None = None  # the rig's ambient, where a hidden temperature starts
    progress: bool = True  # one line per step on the fit's stream


@dataclass
class Comparison:
    """How the rig differs from the simulation where both reach, and what was corrected.

    ``diagnosis`` is the rig diagnosed against the simulation's model; ``heating_scale`` the
    fitted scale of the diagnosis' temperature convention (None: no hidden temperature to
    correct); ``rig_T`` the rig's temperature as fused (recorded or estimated) per wheel;
    ``rms`` the RMS of rig - model [N] on the rig with the simulation's model at the nominal
    temperature ("uncorrected") and at the rig's estimated one ("corrected"); ``friction``
    the rig's friction as a factor of the simulation's (LMUX, LMUY; fitted with the heating
    scale, None without one); ``overlap_load_pressure`` and ``overlap`` the share of the rig's
    sweep samples at loads and pressures the simulation covers, and at its temperatures too.
    """

    diagnosis: Diagnosis
    heating_scale: float | None
    rig_T: list[F64 | None]
    T_ambient_C: float
    rms: dict[str, dict[str, float]]
    overlap: float  # share of the rig's sweep samples in cells the simulation covers
    overlap_load_pressure: float = 0.0  # ... in its load x pressure cells, any temperature
    friction: dict[str, float] | None = None

    @property
    def words(self) -> list[str]:
        return [e.name for e in self.diagnosis.effects]


@dataclass
class ExtendResult:
    """Outcome of :func:`fit_extended`."""

    model: TireModel  # the fused model: ranges and envelope set
    fit: FitResult  # the final (fused) staged fit
    sim_fit: FitResult  # the simulation alone
    comparison: Comparison
    sidewall: SidewallFit | None
    envelope: Envelope
    ranges: dict[str, tuple[float, float]]  # name -> (start value, fused value)
    rig: list[WheelSeries]
    sim: list[WheelSeries]
    sim_used: list[Bools]  # per simulation wheel: samples fitted (beyond the rig)
    sim_corner: list[Bools]  # per simulation wheel: samples in the sidewall corner
    notes: list[str] = field(default_factory=list)


# --- helpers ---------------------------------------------------------------------------------


def _swept(s: WheelSeries) -> Bools:
    out: Bools = (np.abs(s.kappa) > SWEPT_KAPPA) | (np.abs(s.alpha) > SWEPT_ALPHA_RAD)
    return out


def _channel(s: WheelSeries, name: str, nominal: float) -> F64:
    v = getattr(s, name)
    return np.full(len(s), nominal) if v is None else np.asarray(v, dtype=np.float64)


def _without_forces(s: WheelSeries, drop: Bools, channels: Sequence[str] = FORCES) -> WheelSeries:
    """``s`` with the measured ``channels`` set to NaN where ``drop``: the samples stay (time
    and sweeps intact), the fit does not see those forces."""
    changes: dict[str, Any] = {
        c: np.where(drop, np.nan, getattr(s, c)) for c in channels if getattr(s, c) is not None
    }
    return dataclasses.replace(s, **changes)


def _say(options: ExtendOptions, text: str) -> None:
    if options.progress:
        import sys

        stream = options.fit.stream or sys.stderr
        stream.write(f"extend: {text}\n")
        stream.flush()


def envelope_of(
    model: TireModel, wheels: Sequence[WheelSeries], source: int, T: Sequence[F64 | None]
) -> Envelope:
    """The cells the wheels' sweep samples cover (temperature ``T`` per wheel, None: not
    known), marked ``source``."""
    nom = nominal_inputs(model)
    steps = (FZ_STEP_FNOMIN * float(model.params["FNOMIN"]), P_STEP_PA, T_STEP_K)
    known = all(t is not None for t in T)
    env: Envelope | None = None
    for s, t in zip(wheels, T, strict=True):
        keep = _swept(s)
        part = Envelope.from_samples(
            s.Fz[keep],
            _channel(s, "p", nom["p"])[keep],
            None if not known or t is None else t[keep],
            source,
            steps,
            ENVELOPE_MIN_SAMPLES,
        )
        env = part if env is None else env.union(part)
    if env is None:
        raise ValueError("no wheels to take an envelope of")
    return env


# --- 1. the simulation alone -----------------------------------------------------------------


def fit_simulation(
    sim: Sequence[WheelSeries], start: TireModel, options: ExtendOptions
) -> tuple[FitResult, SidewallFit | None, list[Bools]]:
    """The simulation fitted alone, its sidewall corner (when named) left out of Fy and Mz."""
    _say(options, f"fit the simulation alone ({len(sim)} wheel(s))")
    first = fit_recording(sim, start, dataclasses.replace(options.fit))
    sw = find_sidewall(first.model, sim)
    none = [np.zeros(len(s), dtype=bool) for s in sim]
    if sw is None or not sw.named:
        _say(options, "no sidewall contact in the simulation")
        return first, sw, none
    nom_p, FNOMIN = nominal_inputs(start)["p"], float(start.params["FNOMIN"])
    corners = [sw.corner(s, nom_p, FNOMIN) for s in sim]
    _say(options, "sidewall_contact in the simulation: its corner left out of the lateral fit")
    clean = [_without_forces(s, c, ("Fy", "Mz")) for s, c in zip(sim, corners, strict=True)]
    second = fit_recording(clean, start, dataclasses.replace(options.fit))
    sw2 = find_sidewall(second.model, sim)  # against the model the corner did not bend
    if sw2 is not None and sw2.named:
        sw = sw2
        corners = [sw.corner(s, nom_p, FNOMIN) for s in sim]
    _say(
        options,
        f"sidewall_contact: deflection > {sw.params[0]:.2f}, |alpha| > "
        f"{math.degrees(sw.params[1]):.1f} deg ({sw.n_corner} lateral samples, Fy mismatch "
        f"{sw.rms_before:.0f} -> {sw.rms_after:.0f} N)",
    )
    return second, sw, corners


# --- 2. the rig against the simulation -------------------------------------------------------


def heating_scale(
    model: TireModel, rig: Sequence[WheelSeries], rise: Sequence[F64], T_amb: float
) -> tuple[float, dict[str, float]]:
    """The scale s of a hidden temperature rise: the rig's forces best explained by ``model``
    at T = T_amb + s * rise (its temperature terms are known from the simulation's set
    temperatures, so the scale the diagnosis could only fix by convention is measurable).

    A friction level of the rig's own (LMUX, LMUY factors) is fitted with it, so that a
    simulation whose friction is off does not pass for heat. Returns (s, the factors).
    """
    inputs, measured, valid = stack_inputs(model, rig, ("Fx", "Fy"))
    dT = np.concatenate(list(rise))
    rows = np.flatnonzero(valid & np.isfinite(measured["Fx"]) & np.isfinite(measured["Fy"]))
    rows = rows[:: max(1, len(rows) // HEATING_FIT_ROWS)]
    sub = {k: None if v is None else v[rows] for k, v in inputs.items()}
    sig = {c: max(noise_sigma(measured[c]), 1e-6) for c in ("Fx", "Fy")}
    P = model.params

    def resid(x: F64) -> F64:
        sub["T"] = T_amb + x[0] * dT[rows]
        scaled = model.with_params({"LMUX": x[1] * P["LMUX"], "LMUY": x[2] * P["LMUY"]})
        pred = evaluate_on(scaled, sub)
        r = [(np.asarray(getattr(pred, c)) - measured[c][rows]) / sig[c] for c in ("Fx", "Fy")]
        out: F64 = np.nan_to_num(np.concatenate(r), nan=0.0)
        return out

    sol = least_squares(
        resid, np.array([1.0, 1.0, 1.0]), bounds=([0.0, 0.5, 0.5], [HEATING_SCALE_MAX, 1.5, 1.5]),
        loss="cauchy", f_scale=3.0, x_scale=[0.3, 0.02, 0.02],
    )  # fmt: skip
    return float(sol.x[0]), {"LMUX": float(sol.x[1]), "LMUY": float(sol.x[2])}


def _rms(model: TireModel, rig: Sequence[WheelSeries], T: Sequence[F64 | None]) -> dict[str, float]:
    """RMS of measured - model Fx, Fy [N] on the rig's sweep samples at temperatures ``T``."""
    parts = [
        dataclasses.replace(s, T=t).select(_swept(s)) if t is not None else s.select(_swept(s))
        for s, t in zip(rig, T, strict=True)
    ]
    inputs, measured, valid = stack_inputs(model, parts, ("Fx", "Fy"))
    out = evaluate_on(model, inputs)
    res = {}
    for c in ("Fx", "Fy"):
        d = (np.asarray(getattr(out, c)) - measured[c])[valid]
        d = d[np.isfinite(d)]
        res[c] = float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
    return res


def compare(
    rig: Sequence[WheelSeries],
    sim_model: TireModel,
    sim_env: Envelope,
    options: ExtendOptions,
    sim_env_load_pressure: Envelope | None = None,
) -> Comparison:
    """Diagnose the rig against the simulation's model; correct a concealed temperature.
    ``sim_env_load_pressure``: the simulation's cells in load and pressure alone (for the
    overlap at any temperature; default ``sim_env``)."""
    from tire_model_ros.diagnosis import diagnose

    _say(options, "diagnose the rig against the simulation's model (where they differ)")
    names = [s.prefix for s in rig]
    if len(set(names)) < len(names):  # one wheel per recording: the diagnosis keys by prefix
        rig = [dataclasses.replace(s, prefix=f"{s.prefix}#{i}") for i, s in enumerate(rig)]
    diag = diagnose(list(rig), sim_model)
    words = ", ".join(e.name for e in diag.effects)
    _say(options, f"the rig differs from the simulation by: {words}")
    nom_T = nominal_inputs(sim_model)["T"]
    T_amb = nom_T if options.rig_ambient_C is None else float(options.rig_ambient_C)
    rig_T: list[F64 | None] = [None if s.T is None else np.asarray(s.T) for s in rig]
    hidden = next((e for e in diag.effects if e.name == "temperature" and e.concealed), None)
    scale, level = None, None
    if hidden is not None and all(s.T is None for s in rig):
        conv = float(hidden.parameters.get("T_amb_C", nom_T))
        rise = [np.asarray(diag.inferred[s.prefix]["T"]) - conv for s in rig]
        scale, level = heating_scale(sim_model, rig, rise, T_amb)
        rig_T = [T_amb + scale * r for r in rise]
        _say(
            options,
            f"concealed temperature corrected: the rig's tyre {T_amb:.0f} -> "
            f"{max(float(np.max(t)) for t in rig_T if t is not None):.0f} degC "
            f"(the diagnosis' rise x {scale:.2f}, fitted with the simulation's temperature terms"
            f"; the rig's friction {level['LMUX']:.3f} x / {level['LMUY']:.3f} y of the "
            "simulation's)",
        )
    uncorrected = [None if s.T is None else np.asarray(s.T) for s in rig]
    rms = {
        "uncorrected": _rms(sim_model, rig, uncorrected),
        "corrected": _rms(sim_model, rig, rig_T),
    }
    covered = np.concatenate(
        [
            sim_env.contains(
                s.Fz, _channel(s, "p", nominal_inputs(sim_model)["p"]),
                np.full(len(s), T_amb) if t is None else t,
            )[_swept(s)]
            for s, t in zip(rig, rig_T, strict=True)
        ]
    )  # fmt: skip
    overlap = float(np.mean(covered)) if len(covered) else 0.0
    lp = sim_env_load_pressure or sim_env
    nom_p = nominal_inputs(sim_model)["p"]
    in_lp = [
        lp.contains(s.Fz, _channel(s, "p", nom_p), np.full(len(s), T_amb))[_swept(s)] for s in rig
    ]
    overlap_lp = float(np.mean(np.concatenate(in_lp))) if sum(map(len, in_lp)) else 0.0
    return Comparison(diag, scale, rig_T, T_amb, rms, overlap, overlap_lp, level)


# --- 3. the fused fit, 4. ranges and envelope ------------------------------------------------


def at_ambient(
    wheels: Sequence[WheelSeries], T: Sequence[F64 | None], ambient_C: float
) -> list[F64 | None]:
    """Each wheel's temperature ``T``, the ambient [degC] where it is not known."""
    return [np.full(len(s), ambient_C) if t is None else t for s, t in zip(wheels, T, strict=True)]


def fused_ranges(
    start: TireModel, wheels: Sequence[WheelSeries], T: Sequence[F64 | None]
) -> tuple[dict[str, float], list[str]]:
    """PRESMIN/PRESMAX, FZMIN/FZMAX, TEMPMIN/TEMPMAX of the fitted sweep samples (the file's
    nominal load and pressure kept inside, as a .tir must), and notes on what was widened."""
    nom = nominal_inputs(start)
    P = start.params
    keep = [_swept(s) for s in wheels]
    Fz = np.concatenate([s.Fz[k] for s, k in zip(wheels, keep, strict=True)])
    p = np.concatenate([_channel(s, "p", nom["p"])[k] for s, k in zip(wheels, keep, strict=True)])
    out = {
        "FZMIN": min(float(np.min(Fz)), float(P["FNOMIN"])),
        "FZMAX": max(float(np.max(Fz)), float(P["FNOMIN"])),
        "PRESMIN": min(float(np.min(p)), float(P["NOMPRES"])),
        "PRESMAX": max(float(np.max(p)), float(P["NOMPRES"])),
    }
    if all(t is not None for t in T):
        Ts = np.concatenate([t[k] for t, k in zip(T, keep, strict=True) if t is not None])
        out.update({"TEMPMIN": float(np.min(Ts)), "TEMPMAX": float(np.max(Ts))})
    rounded = {k: _round_out(k, v) for k, v in out.items()}
    notes = [
        f"{k} {P[k]:g} -> {v:g}"
        for k, v in rounded.items()
        if not math.isclose(float(P.get(k, v)), v, rel_tol=1e-9)
    ]
    return rounded, notes


def _round_out(name: str, value: float) -> float:
    """A range end rounded outward to a readable unit (1 N, 100 Pa, 0.1 degC)."""
    unit = {"FZ": 1.0, "PR": 100.0, "TE": 0.1}[name[:2]]
    f = math.floor if name.endswith("MIN") else math.ceil
    return round(f(value / unit) * unit, 6)


def trend_terms(sim_fit: FitResult) -> frozenset[str]:
    """The coefficients the simulation's fit tried, but the rig's LEVELS: the shape of the
    curves and how they change with the conditions (load, camber, pressure, temperature)."""
    tried = {k for entry in sim_fit.report["stages"] for k in entry.get("names", ())}
    return frozenset(tried - LEVELS)


def _beyond(reach: Envelope, start: TireModel, s: WheelSeries, T: F64 | None) -> Bools:
    """The samples of a simulation wheel outside the cells the rig reaches."""
    nom = nominal_inputs(start)
    T_ = np.full(len(s), nom["T"]) if T is None or reach.T_step_K == 0.0 else T
    out: Bools = ~reach.contains(s.Fz, _channel(s, "p", nom["p"]), T_)
    return out


def fit_extended(
    rig: Sequence[WheelSeries],
    sim: Sequence[WheelSeries],
    start: TireModel,
    options: ExtendOptions | None = None,
) -> ExtendResult:
    """The rig's recordings fused with a simulation (the module's steps 1-4).

    Parameters
    ----------
    rig, sim : the wheels of the rig's and of the simulation's recordings (one tyre).
    start : the start model (its coefficients are the start values of the simulation's fit).
    options : see :class:`ExtendOptions`.

    Returns
    -------
    ExtendResult
        The fused model (coefficients, ranges, ``[FIT_ENVELOPE]``), the fits and the
        comparison, for the report.
    """
    options = options or ExtendOptions()
    if not rig or not sim:
        raise ValueError("fit --extend needs rig recordings and simulation recordings")
    # The fits must see the data's loads and pressures unsaturated: a start file's PRESMIN
    # (MF 6.1's 200 kPa) would clip a 60 kPa simulation to 200 kPa in every fit.
    wide, _ = fused_ranges(start, [*rig, *sim], [None] * (len(rig) + len(sim)))
    base = start.with_params({k: min(v, start.params[k]) if k.endswith("MIN") else
                              max(v, start.params[k]) for k, v in wide.items()})  # fmt: skip
    sim_fit, sw, corners = fit_simulation(sim, base, options)
    sim_T = [None if s.T is None else np.asarray(s.T) for s in sim]
    sim_env = envelope_of(start, sim, SIMULATION, sim_T)
    sim_lp = envelope_of(start, sim, SIMULATION, [None] * len(sim))  # load x pressure only
    comp = compare(rig, sim_fit.model, sim_env, options, sim_lp)
    # A rig wheel at an unknown temperature (no channel, no heating found) counts as the
    # ambient's, in the envelope and in the temperature range alike.
    rig_T = at_ambient(rig, comp.rig_T, comp.T_ambient_C) if sim_env.T_step_K > 0 else comp.rig_T
    rig_env = envelope_of(start, rig, RIG, rig_T)
    rig_fused = [
        s if t is None else dataclasses.replace(s, T=t)
        for s, t in zip(rig, comp.rig_T, strict=True)
    ]
    trends = trend_terms(sim_fit)
    _say(options, f"fit the rig's levels, the simulation's {len(trends)} trend terms kept")
    final = fit_recording(
        rig_fused, sim_fit.model, dataclasses.replace(options.fit, fixed=options.fit.fixed | trends)
    )
    used = [_beyond(rig_env.filled(), start, s, t) for s, t in zip(sim, sim_T, strict=True)]
    envelope = rig_env.union(sim_env).filled()
    ranges, notes = fused_ranges(start, [*rig, *sim], [*rig_T, *sim_T])
    model = TireModel(envelope.into(final.model.with_params(ranges).tir))
    before = {k: (float(start.params.get(k, v)), v) for k, v in ranges.items()}
    return ExtendResult(
        model, final, sim_fit, comp, sw, envelope, before, list(rig), list(sim), used, corners,
        [f"range {n}" for n in notes],
    )  # fmt: skip


def sources(result: ExtendResult) -> Mapping[str, Any]:
    """Samples each source gave the fused fit (JSON-ready)."""
    return {
        "rig_samples": int(sum(len(s) for s in result.rig)),
        "simulation_samples": int(sum(len(s) for s in result.sim)),
        "simulation_fitted": int(sum(int(u.sum()) for u in result.sim_used)),
        "simulation_in_rig_cells": int(sum(int((~u).sum()) for u in result.sim_used)),
        "sidewall_corner": int(sum(int(c.sum()) for c in result.sim_corner)),
    }
