"""simulate_session: run a programme on the virtual rig and return recordings plus the truth.

Order of the physics per wheel (one programme sample = one ``slip`` message):

1. true inputs from the programme; ``load_ripple`` modulates the true load at wheel frequency;
2. ``relaxation`` filters the slips in travelled distance -> the slips the contact patch has;
3. friction/stiffness scales: ``speed_friction`` (Savkoor, on the sliding speed), ``mu_step``
   (belt friction step), ``wear`` (frictional work, weighted by the tread's heat),
   ``heating`` (surface grip window, carcass stiffness) -- the thermal nodes always run so the
   temperature sensor has something to read; ``gas_pressure`` feeds the gas-law pressure to
   the model;
4. base forces = TireModel.evaluate on the effective inputs, friction scaled by the
   similarity method (F = mu F_model(s x / mu)) and, with ``combined``, pure-slip forces
   combined by normalised total slip instead of the file's G functions; the thermal loop is
   iterated to a fixed point (power -> temperature -> forces);
5. force-level effects: ``sidewall`` (contact at low pressure and high load), ``offset``,
   ``camber`` (extra thrust), ``delay`` (forces late);
6. sensors: noise on every recorded channel; temperature = tread surface seen by an IR
   sensor (lag 0.3 s); channels in ``omit`` are left out (None).

An isothermal programme (``special_conditions``: a simulation, like an FE model) holds the tyre
at its set temperature instead of step 3's heating: the ``heating`` effect's temperature law
(grip window, stiffness) acts at the set temperature, nothing heats, the pressure is the set
one, and the temperature and pressure channels are those set values.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..model import TireModel
from ..model.tir import TirData
from ..recording.series import WheelSeries
from . import effects as fx
from .effects import EffectsSpec
from .programmes import (
    BELT_STOP,
    Programme,
    Segment,
    TyreInfo,
    WheelProgramme,
    build_programme,
)
from .thermal import (
    HeatingParams,
    frictional_power,
    gas_law_pressure,
    grip_factor,
    integrate_nodes,
    stiffness_factor,
)
from .track import invert_pure

F64 = npt.NDArray[np.float64]
#: Switched-on effects with their parameters (``effects.resolve_effects``).
Effects = dict[str, dict[str, float]]

EPOCH_NS = 1_767_225_600 * 10**9  # 2026-01-01T00:00:00Z: fixed, so bags are reproducible
OMITTABLE = ("temperature", "pressure", "velocity", "moments")
IR_SENSOR_TAU_S = 0.3
TRUTH_VERSION = 1
MAX_THERMAL_ITERATIONS = 16  # Picard iterations power -> temperature -> forces (tol 1e-3)


def _as_model(tir_or_model: str | os.PathLike[str] | TireModel | TirData) -> TireModel:
    if isinstance(tir_or_model, TireModel):
        return tir_or_model
    if isinstance(tir_or_model, str | os.PathLike):
        return TireModel.from_file(tir_or_model)
    return TireModel(tir_or_model)  # a TirData


# ------------------------------------------------------------------ tyre forces


def _combined_similarity(
    model: TireModel,
    Fz: F64,
    kappa: F64,
    alpha: F64,
    gamma: F64,
    Vx: F64,
    p: F64,
    T: F64 | None,
    peak_scale: float,
) -> dict[str, F64]:
    """Combined slip by normalised total slip (similarity method, Pacejka 2012 §4.3.3 idea):
    sx = k/(1+k), sy = tan a/(1+k), each divided by its peak-ish slip mu Fz/K; the pure-slip
    curves are read at the total normalised slip and shared by direction."""
    zero = np.zeros_like(Fz)
    o0 = model.evaluate(Fz, zero, zero, gamma, Vx, p, T)
    sx_ref = peak_scale * np.maximum(np.abs(o0.mux) * Fz, 1e-6) / np.maximum(np.abs(o0.Kxk), 1.0)
    sy_ref = peak_scale * np.maximum(np.abs(o0.muy) * Fz, 1e-6) / np.maximum(np.abs(o0.Kya), 1.0)
    one_k = np.maximum(1.0 + kappa, 0.05)
    sx, sy = kappa / one_k, np.tan(alpha) / one_k
    nx, ny = sx / sx_ref, sy / sy_ref
    n = np.hypot(nx, ny)
    safe = np.where(n > 1e-12, n, 1.0)
    wx = np.where(n > 1e-12, np.abs(nx) / safe, 1.0)
    wy = np.where(n > 1e-12, np.abs(ny) / safe, 1.0)
    sx_e = np.clip(np.sign(sx) * n * sx_ref, -0.95, 0.95)
    kappa_e = sx_e / (1.0 - sx_e)
    alpha_e = np.arctan(np.sign(sy) * n * sy_ref)
    ox = model.evaluate(Fz, kappa_e, zero, gamma, Vx, p, T)
    oy = model.evaluate(Fz, zero, alpha_e, gamma, Vx, p, T)
    Fx = o0.Fx + (ox.Fx - o0.Fx) * wx
    Fy = o0.Fy + (oy.Fy - o0.Fy) * wy
    Mz = o0.Mz + (oy.Mz - o0.Mz) * wy
    return {"Fx": Fx, "Fy": Fy, "Mz": Mz, "Mx": oy.Mx, "My": ox.My}


def tyre_forces(
    model: TireModel,
    Fz: F64,
    kappa: F64,
    alpha: F64,
    gamma: F64,
    Vx: F64,
    p: F64,
    T: F64 | None,
    mu: F64,
    stiff: F64,
    combined: Mapping[str, float] | None,
) -> dict[str, np.ndarray]:
    """Forces of the tyre on effective inputs with friction scale ``mu`` and slip-stiffness
    scale ``stiff`` (similarity method: F = mu F_model(stiff x / mu))."""
    r = stiff / mu
    km = kappa * r
    am = np.arctan(np.tan(alpha) * r)
    if combined is not None:
        f = _combined_similarity(model, Fz, km, am, gamma, Vx, p, T, combined["peak_scale"])
    else:
        o = model.evaluate(Fz, km, am, gamma, Vx, p, T)
        f = {"Fx": o.Fx, "Fy": o.Fy, "Mz": o.Mz, "Mx": o.Mx, "My": o.My}
    return {
        "Fx": mu * f["Fx"],
        "Fy": mu * f["Fy"],
        "Mz": mu * f["Mz"],
        "Mx": f["Mx"],
        "My": f["My"],
    }


# ------------------------------------------------------------------ one wheel


def _true_load(
    Fz_set: F64, V: F64, tyre: TyreInfo, eff: Effects, rng: np.random.Generator, dt: float
) -> np.ndarray:
    """The load the tyre carries: the set load, with ``load_ripple`` at wheel frequency."""
    if "load_ripple" not in eff:
        return Fz_set.copy()
    lr = eff["load_ripple"]
    phase = np.cumsum(np.abs(V) / tyre.R0) * dt * lr["harmonic"] + rng.uniform(0, 2 * math.pi)
    return Fz_set * (1.0 + lr["amplitude"] * np.sin(phase))


def _contact_slips(
    wp: WheelProgramme, Fz: F64, FN: float, eff: Effects, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slips the contact patch has: ``relaxation`` lags them in travelled distance."""
    if "relaxation" not in eff:
        return wp.kappa.copy(), wp.alpha.copy()
    rx = eff["relaxation"]
    sig_a = fx.relaxation_length_alpha(Fz, FN, rx["sigma_alpha_m"], bool(rx["load_dependent"]))
    alpha = np.arctan(fx.first_order_in_distance(np.tan(wp.alpha), wp.Vx, sig_a, dt))
    kappa = fx.first_order_in_distance(wp.kappa, wp.Vx, np.full(len(Fz), rx["sigma_kappa_m"]), dt)
    return kappa, alpha


def _static_friction(
    prog: Programme, tyre: TyreInfo, V: F64, kappa: F64, alpha: F64, eff: Effects
) -> tuple[np.ndarray, float | None]:
    """Friction scales that do not depend on the thermal state: speed law and belt step."""
    n = len(V)
    mu = np.ones(n)
    if "speed_friction" in eff:
        sf = eff["speed_friction"]
        Vs_ref = sf["Vs_ref_mps"] if sf["Vs_ref_mps"] > 0 else 0.14 * tyre.LONGVL
        law = (sf["mu0_ratio"], sf["Vm_mps"], sf["h"])
        mu *= fx.savkoor_factor(fx.sliding_speed(V, kappa, alpha), *law) / fx.savkoor_factor(
            np.array([Vs_ref]), *law
        )
    step_at = None
    if "mu_step" in eff:
        ms = eff["mu_step"]
        step_at = ms["at_s"] if ms["at_s"] >= 0 else _between_runs(prog)
        mu *= np.where(np.arange(n) / prog.rate_hz >= step_at, ms["ratio"], 1.0)
    return mu, step_at


def _isothermal(
    model: TireModel,
    wp: WheelProgramme,
    Fz: F64,
    kappa: F64,
    alpha: F64,
    mu_static: F64,
    eff: Effects,
) -> dict[str, Any]:
    """Forces of a tyre held at its set temperature: the temperature law of ``heating`` at
    T_set, no frictional heating, the set pressure (no gas law)."""
    assert wp.T_set is not None
    T = wp.T_set
    mu, stiff = mu_static.copy(), np.ones(len(T))
    if "heating" in eff:
        hp = HeatingParams.from_dict(eff["heating"])
        mu *= grip_factor(T, T, hp)
        stiff = stiffness_factor(T, hp)
    T_model = T if "model_temperature" in eff else None
    forces = tyre_forces(
        model, Fz, kappa, alpha, wp.gamma, wp.Vx, wp.p_set, T_model, mu, stiff,
        eff.get("combined"),
    )  # fmt: skip
    return {
        "forces": forces,
        "T_surface": T,
        "T_bulk": T,
        "T_gas": T,
        "p_true": wp.p_set.copy(),
        "mu_factor": mu,
        "stiffness_factor": stiff,
        "P_fric": frictional_power(forces["Fx"], forces["Fy"], wp.Vx, kappa, alpha),
        "iterations": 1,
    }


def _thermal_fixed_point(
    model: TireModel,
    prog: Programme,
    wp: WheelProgramme,
    tyre: TyreInfo,
    Fz: F64,
    kappa: F64,
    alpha: F64,
    mu_static: F64,
    eff: Effects,
) -> dict[str, Any]:
    """Forces and hidden states consistent with each other: power -> nodes -> grip/pressure
    -> forces, iterated (Picard) until the power changes by < 0.1 % of its peak."""
    dt = 1.0 / prog.rate_hz
    hp = HeatingParams.from_dict(eff.get("heating", {}))
    heating, wear, gas = "heating" in eff, "wear" in eff, "gas_pressure" in eff
    coupled = heating or wear or gas or "model_temperature" in eff
    n = len(Fz)
    P = None
    mu, stiff, p_true = mu_static.copy(), np.ones(n), wp.p_set.copy()
    Ts = Tb = Tg = np.full(n, float(prog.T_ambient[0]))
    for iteration in range(MAX_THERMAL_ITERATIONS):
        T_model = Ts if "model_temperature" in eff else None
        forces = tyre_forces(
            model,
            Fz,
            kappa,
            alpha,
            wp.gamma,
            wp.Vx,
            p_true,
            T_model,
            mu,
            stiff,
            eff.get("combined"),
        )
        P_new = frictional_power(forces["Fx"], forces["Fy"], wp.Vx, kappa, alpha)
        converged = P is not None and np.max(np.abs(P_new - P)) < 1e-3 * (np.max(P_new) + 1.0)
        P = P_new
        Ts, Tb, Tg = integrate_nodes(P, tyre.FNOMIN, prog.T_ambient, dt, hp)
        if not coupled or converged or iteration == MAX_THERMAL_ITERATIONS - 1:
            break  # the hidden mu/stiffness stay those the final forces used
        mu = mu_static.copy()
        if heating:
            mu *= grip_factor(Ts, Tb, hp)
            stiff = stiffness_factor(Tb, hp)
        if wear:
            mu *= _wear_factor(P, Ts, prog.T_ambient, dt, tyre.FNOMIN, eff["wear"])
        if gas:
            p_true = gas_law_pressure(wp.p_set, Tg, prog.run)
    return {
        "forces": forces,
        "T_surface": Ts,
        "T_bulk": Tb,
        "T_gas": Tg,
        "p_true": p_true,
        "mu_factor": mu,
        "stiffness_factor": stiff,
        "P_fric": P,
        "iterations": iteration + 1,
    }


def _wear_factor(
    P: F64, Ts: F64, T_amb: F64, dt: float, FNOMIN: float, wp: Mapping[str, float]
) -> np.ndarray:
    """Grip left after abrasion: the worn depth grows with the frictional power, faster on a
    hot tread (1 + abrasion_per_K (Ts - T_amb)); grip falls linearly with it (floor 0.2)."""
    rate = P * (1.0 + wp["abrasion_per_K"] * np.maximum(Ts - T_amb, 0.0))
    worn = np.concatenate([[0.0], np.cumsum(rate[:-1]) * dt])  # J-equivalent
    return np.maximum(1.0 - wp["loss_per_km"] * worn / FNOMIN / 1000.0, 0.2)


def _force_effects(
    forces: Mapping[str, F64],
    Fz: F64,
    p: F64,
    gamma: F64,
    alpha: F64,
    t_rel: npt.NDArray[np.floating[Any]],
    eff: Effects,
    params: Mapping[str, float],
) -> dict[str, F64]:
    """What the load cell reports: the hub forces with ``sidewall`` contact (at the true load
    and pressure ``p``), ``offset`` and ``camber`` added, ``delay``-ed against the slip
    channel."""
    Fy_extra, Fx_extra, Mz_extra = np.zeros_like(Fz), np.zeros_like(Fz), np.zeros_like(Fz)
    if "sidewall" in eff:
        left = fx.sidewall_factor(Fz, p, alpha, params, eff["sidewall"])
        forces = {**forces, "Fy": forces["Fy"] * left, "Mz": forces["Mz"] * left}
    if "offset" in eff:
        of = eff["offset"]
        Fy_extra += of["fy_per_Fz"] * Fz + of["fy_N"]
        Fx_extra += of["fx_per_Fz"] * Fz + of["fx_N"]
        Mz_extra += of["mz_Nm"]
    if "camber" in eff:
        cb = eff["camber"]
        Fy_extra += fx.camber_thrust(
            Fz, gamma, alpha, cb["per_deg"], cb["saturation_deg"], cb["fade_deg"]
        )
    true_forces = {
        "Fx": forces["Fx"] + Fx_extra,
        "Fy": forces["Fy"] + Fy_extra,
        "Fz_meas": Fz.copy(),
        "Mx": forces["Mx"],
        "My": forces["My"],
        "Mz": forces["Mz"] + Mz_extra,
    }
    if "delay" in eff:
        return {k: fx.delayed(v, t_rel, eff["delay"]["tau_s"]) for k, v in true_forces.items()}
    return true_forces


def _sensors(
    wp: WheelProgramme,
    Fz: F64,
    hid: Mapping[str, Any],
    meas: Mapping[str, F64],
    tyre: TyreInfo,
    eff: Effects,
    rng: np.random.Generator,
    dt: float,
) -> dict[str, F64]:
    """What the rig's sensors record: commanded slips, load cell, IR tread temperature
    (first order, IR_SENSOR_TAU_S), gauge pressure, belt speed, forces; plus noise."""
    n = len(Fz)
    T_sensor = fx.first_order_in_distance(
        hid["T_surface"], np.ones(n), np.full(n, IR_SENSOR_TAU_S), dt
    )  # in time: V = 1
    set_values = {"T": wp.T_set, "p": hid["p_true"]} if wp.T_set is not None else {}
    load = Fz if eff.get("load_ripple", {}).get("recorded", 1.0) else wp.Fz.copy()
    rec = {
        "kappa": wp.kappa,
        "alpha": wp.alpha,
        "gamma": wp.gamma,
        "Fz": load,
        "Vx": wp.Vx,
        "p": hid["p_true"],
        "T": T_sensor,
        **meas,
    }
    if "noise" in eff:
        nz = eff["noise"]
        sds = fx.noise_sd(tyre.FNOMIN, tyre.R0)
        rec = {
            k: v + fx.coloured_noise(rng, n, sds[k] * nz["scale"], nz["colour"], nz["tau_s"], dt)
            for k, v in rec.items()
        }
    return {**rec, **set_values}  # an isothermal run's set temperature and pressure are exact


def _simulate_wheel(
    model: TireModel,
    tyre: TyreInfo,
    prog: Programme,
    wp: WheelProgramme,
    eff: Effects,
    omit: set[str],
    rng: np.random.Generator,
    trace_hz: float,
) -> tuple[WheelSeries, dict[str, Any]]:
    dt = 1.0 / prog.rate_hz
    n = len(wp.Fz)
    t_rel = np.arange(n) * dt
    Fz = _true_load(wp.Fz, wp.Vx, tyre, eff, rng, dt)
    kappa, alpha = _contact_slips(wp, Fz, tyre.FNOMIN, eff, dt)
    mu_static, step_at = _static_friction(prog, tyre, wp.Vx, kappa, alpha, eff)
    if prog.isothermal:
        hid = _isothermal(model, wp, Fz, kappa, alpha, mu_static, eff)
    else:
        hid = _thermal_fixed_point(model, prog, wp, tyre, Fz, kappa, alpha, mu_static, eff)
    meas = _force_effects(
        hid["forces"], Fz, hid["p_true"], wp.gamma, alpha, t_rel, eff, model.params
    )
    rec = _sensors(wp, Fz, hid, meas, tyre, eff, rng, dt)
    moments = {k: None if "moments" in omit else rec[k] for k in ("Mx", "My", "Mz")}
    t_ns = EPOCH_NS + np.round(np.arange(n) * (1e9 / prog.rate_hz)).astype(np.int64)
    series = WheelSeries(
        prefix=wp.prefix,
        t=t_ns / 1e9,
        kappa=rec["kappa"],
        alpha=rec["alpha"],
        gamma=rec["gamma"],
        Fz=rec["Fz"],
        p=None if "pressure" in omit else rec["p"],
        T=None if "temperature" in omit else rec["T"],
        Vx=None if "velocity" in omit else rec["Vx"],
        Fx=rec["Fx"],
        Fy=rec["Fy"],
        Fz_meas=rec["Fz_meas"],
        Mx=moments["Mx"],
        My=moments["My"],
        Mz=moments["Mz"],
        meta={"t_ns": t_ns, "source": "virtual rig", "programme": prog.name},
    )
    hidden = {**hid, "alpha_eff": alpha, "kappa_eff": kappa, "Fz_true": Fz}
    E_total = float(np.sum(hid["P_fric"]) * dt)
    truth = _wheel_truth(wp, prog, hidden, E_total, step_at, trace_hz)
    truth["hidden_summary"]["thermal_iterations"] = hid["iterations"]
    return series, truth


def _between_runs(prog: Programme) -> float:
    """Where a belt change falls [s from start]: the middle of the first belt stop, else the
    segment start nearest the middle of the session."""
    stops = [s for s in prog.wheels[0].segments if s.label == BELT_STOP]
    if stops:
        return 0.5 * (stops[0].i0 + stops[0].i1) / prog.rate_hz
    starts = np.array([s.i0 for s in prog.wheels[0].segments if s.kind != "transition"])
    mid = prog.n / 2
    return float(starts[np.argmin(np.abs(starts - mid))] / prog.rate_hz)


def _sweep_summary(seg: Segment, hidden: Mapping[str, Any]) -> dict[str, Any]:
    """Per sweep: surface temperature rise and grip factor loss (true, hidden)."""
    sl = slice(seg.i0, seg.i1)
    Ts, mu = hidden["T_surface"][sl], hidden["mu_factor"][sl]
    out = {
        "T_surface_start_C": float(Ts[0]),
        "T_surface_peak_C": float(Ts.max()),
        "dT_surface_K": float(Ts.max() - Ts[0]),
        "mu_factor_start": float(mu[0]),
        "mu_factor_min": float(mu.min()),
    }
    return out


def _wheel_truth(
    wp: WheelProgramme,
    prog: Programme,
    hidden: Mapping[str, Any],
    E_total: float,
    step_at: float | None,
    trace_hz: float,
) -> dict[str, Any]:
    fs = prog.rate_hz
    step = max(1, round(fs / trace_hz)) if trace_hz > 0 else 0
    segments = []
    for s in wp.segments:
        d = s.to_json(fs)
        if s.kind.endswith("sweep"):
            d["hidden"] = _sweep_summary(s, hidden)
        segments.append(d)
    summary = {
        "T_surface_peak_C": float(hidden["T_surface"].max()),
        "T_surface_end_C": float(hidden["T_surface"][-1]),
        "T_bulk_peak_C": float(hidden["T_bulk"].max()),
        "T_gas_peak_C": float(hidden["T_gas"].max()),
        "p_true_min_Pa": float(hidden["p_true"].min()),
        "p_true_max_Pa": float(hidden["p_true"].max()),
        "mu_factor_min": float(hidden["mu_factor"].min()),
        "mu_factor_max": float(hidden["mu_factor"].max()),
        "mu_factor_end": float(hidden["mu_factor"][-1]),
        "stiffness_factor_min": float(hidden["stiffness_factor"].min()),
        "frictional_work_J": E_total,
        "Fz_true_min_N": float(hidden["Fz_true"].min()),
        "Fz_true_max_N": float(hidden["Fz_true"].max()),
    }
    if step_at is not None:
        summary["mu_step_at_s"] = step_at
    out = {"segments": segments, "hidden_summary": summary}
    if step:
        idx = np.arange(0, len(wp.Fz), step)
        out["hidden_trace"] = {
            "t_s": (idx / fs).round(6).tolist(),
            **{
                k: np.round(hidden[k][idx], 6).tolist()
                for k in ("T_surface", "T_bulk", "T_gas", "p_true", "mu_factor", "stiffness_factor")
            },
        }
    return out


# ------------------------------------------------------------------ public API


def simulate_session(
    tir_or_model: str | os.PathLike[str] | TireModel,
    programme: str,
    *,
    effects: EffectsSpec = None,
    omit: Sequence[str] | None = None,
    seed: int = 0,
    rate_hz: float = 100.0,
    programme_options: Mapping[str, Any] | None = None,
    truth_trace_hz: float = 2.0,
) -> tuple[list[WheelSeries], dict[str, Any]]:
    """Run ``programme`` on the virtual rig with the tyre of ``tir_or_model``.

    Parameters
    ----------
    tir_or_model : TireModel, TirData or path of a .tir file (the base model the rig uses).
    programme : one of ``programmes.PROGRAMMES`` (flat_trac, lateral_sweeps, longitudinal_sweeps,
        combined, camber, pressure, transient, safe_envelope, special_conditions, track).
    effects : effect name -> True / False / dict of parameter overrides (``effects.DEFAULTS``),
        or a list of names. ``noise`` and the programme's own defaults (``heating`` in
        safe_envelope, ``sidewall`` in special_conditions) are on unless given as False.
    omit : recorded channels to leave out: temperature, pressure, velocity, moments; None: the
        programme's default (the temperature in safe_envelope, else nothing).
    seed : all randomness (noise, ripple phase) derives from it: same seed -> same series.
    rate_hz : sample rate of the slip channel (one sample per slip message).
    programme_options : see ``programmes`` (repeats, rate_scale, amplitude_deg, kappa_max,
        speed, ambient_C, vary_pressure, laps).
    truth_trace_hz : rate of the hidden-state trace stored in the truth (0: none).

    Returns
    -------
    (wheels, truth): the recorded WheelSeries (what write_recording writes) and a
    JSON-serialisable truth dict (programme, effects with parameters, omitted channels, seed,
    per-wheel segments and hidden-state summary/trace).
    """
    model = _as_model(tir_or_model)
    bad = set(omit or ()) - set(OMITTABLE)
    if bad:
        raise ValueError(f"cannot omit {sorted(bad)}: omittable channels are {OMITTABLE}")
    params = model.params
    tyre = TyreInfo.from_params(params)
    prog = build_programme(programme, params, rate_hz, programme_options, set(omit or ()))
    omit_set = set(prog.default_omit if omit is None else omit)
    eff = fx.resolve_effects(_with_defaults(prog.default_effects, effects))
    for wp in prog.wheels:
        if getattr(wp, "needs_slip_inversion", False):  # track: force demands -> slips
            wp.alpha = invert_pure(model, wp.Fz, wp.alpha, wp.Vx, wp.p_set, lateral=True)
            wp.kappa = invert_pure(model, wp.Fz, wp.kappa, wp.Vx, wp.p_set, lateral=False)
    seeds = np.random.SeedSequence(int(seed)).spawn(len(prog.wheels))
    wheels, wheel_truth = [], {}
    for wp, ss in zip(prog.wheels, seeds, strict=True):
        s, tr = _simulate_wheel(
            model, tyre, prog, wp, eff, omit_set, np.random.default_rng(ss), truth_trace_hz
        )
        wheels.append(s)
        wheel_truth[wp.prefix] = tr
    truth = {
        "version": TRUTH_VERSION,
        "generator": "tire_model_ros.rig.simulate_session",
        "tir": getattr(model.tir, "path", None),
        "programme": programme,
        "programme_options": {k: v for k, v in prog.options.items()},
        "duration_s": prog.duration_s,
        "rate_hz": rate_hz,
        "seed": int(seed),
        "effects": eff,
        "effect_words": {k: fx.DIAGNOSIS_WORD.get(k) for k in eff},
        "diagnosis_words": sorted({fx.DIAGNOSIS_WORD[k] for k in eff if k in fx.DIAGNOSIS_WORD}),
        "omitted": sorted(omit_set),
        "concealed": _concealed(eff, omit_set),
        "isothermal": prog.isothermal,
        "ambient_C": float(prog.T_ambient[0]),
        "wheels": wheel_truth,
    }
    return wheels, truth


def _with_defaults(
    defaults: Mapping[str, Mapping[str, float]], effects: EffectsSpec
) -> EffectsSpec:
    """The caller's effects on top of a programme's default ones: a caller's False switches
    one off, a caller's parameters replace the programme's."""
    if not defaults:
        return effects
    if isinstance(effects, str):
        effects = [effects]
    given = dict(effects) if isinstance(effects, Mapping) else dict.fromkeys(effects or (), True)
    merged: dict[str, bool | Mapping[str, float | str] | None] = dict(defaults)
    for name, value in given.items():
        if value is not True or name not in merged:
            merged[name] = value
    return merged


def _concealed(eff: Effects, omit: set[str]) -> list[str]:
    """Effects whose driving channel is not in the bag."""
    out = []
    if "heating" in eff and "temperature" in omit:
        out.append("heating")
    if "gas_pressure" in eff and "pressure" in omit:
        out.append("gas_pressure")
    return out


# ------------------------------------------------------------------ writing


def truth_path(bag: str | Path) -> Path:
    """``<BAG>.truth.json`` beside the bag (never inside a bag folder)."""
    bag = Path(bag)
    return bag.with_name(bag.name + ".truth.json")


SENSOR_RATES_HZ = {"pressure": 10.0, "temperature": 10.0}  # slow sensors of the rig


def write_session(
    bag: str | Path,
    wheels: Sequence[WheelSeries],
    truth: Mapping[str, Any],
    *,
    overwrite: bool = False,
) -> tuple[Path, Path]:
    """Write the bag (write_recording, MCAP) and its truth file beside it, both atomically."""
    from ..recording import write_recording

    bag = Path(bag)
    tpath = truth_path(bag)
    if not overwrite:
        for p in (bag, tpath):
            if p.exists():
                raise FileExistsError(f"{p}: exists already (use --force / overwrite=True)")
    truth = {**truth, "bag": bag.name, "sensor_rates_hz": SENSOR_RATES_HZ}
    write_recording(bag, wheels, overwrite=overwrite, rates=SENSOR_RATES_HZ)
    tmp = tpath.with_name(f".{tpath.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(truth, indent=1, allow_nan=False) + "\n")
        os.replace(tmp, tpath)
    finally:
        if tmp.exists():
            tmp.unlink()
    return bag, tpath
