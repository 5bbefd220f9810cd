"""The cases: which effects, their sizes, the programme, the sensors, and the outputs."""

from __future__ import annotations

import json
import math
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realities._bag import write_bag
from tire_model_ros.model import TireModel, write_tir

from . import fit as ft
from . import programme as pg
from . import sim
from . import tyre as ty

NAME = "brush"
PREFIX = "/rig/wheel"
CASES = ["heat_below", "heat_above", "heat_cross", "heat_recorded", "pressure_sealed",
         "pressure_leak", "pressure_recorded", "wear", "relaxation", "delay", "offset", "speed",
         "camber", "combined", "sidewall", "multi2_a", "multi2_b", "multi3",
         "null_1", "null_2", "null_3", "null_4", "null_5", "null_6"]  # fmt: skip
MULTI_POOL = ["temperature", "pressure", "offset", "relaxation", "time_delay", "drift", "speed"]

# thermal model per tyre kind (randomised per seed by x0.8..1.25)
THERMAL = {
    "fsae": dict(
        CS=200.0,
        CB=6000.0,
        CG=1800.0,
        HSB=32.0,
        HSA=14.0,
        HBA=13.0,
        HBG=6.0,
        HGA=5.0,
        ETA=0.45,
        ETAR=1.0,
    ),  # fmt: skip
    "car": dict(
        CS=520.0,
        CB=16000.0,
        CG=5000.0,
        HSB=75.0,
        HSA=35.0,
        HBA=32.0,
        HBG=14.0,
        HGA=12.0,
        ETA=0.45,
        ETAR=1.0,
    ),  # fmt: skip
}
# grip optimum of the compound [degC]; heat_above uses a soft compound whose window sits
# lower (on a rig the tread rarely runs hotter than ~90 degC)
COMPOUND = {"fsae": (70.0, 110.0), "car": (60.0, 100.0)}
COMPOUND_SOFT = {"fsae": (40.0, 70.0), "car": (40.0, 65.0)}


def lerp(lo, hi, x):
    return lo + (hi - lo) * x


@dataclass
class Effect:
    name: str  # INTERFACE word
    concealed: bool
    knob: float  # 0..1 within the physical range (below 0: smaller than the range start)
    fixed: dict = field(default_factory=dict)  # random choices not scaled by the knob
    kind: str = ""  # sub-kind (temperature side, pressure mode)
    sizable: bool = True


@dataclass
class Session:
    case: str
    seed: int
    minutes: float
    variant: ty.Variant
    T: np.ndarray
    tir: object  # TirData of model.tir
    tir_nominal: object
    fit_report: dict
    prog: pg.Programme
    E_base: np.ndarray
    effects: list
    topics: dict
    noise: dict
    imperfections: list
    Tnom: float
    description: str = ""


# ------------------------------------------------------------------------------------------
# effect parameters
# ------------------------------------------------------------------------------------------
def effect_params(s: Session, eff: Effect) -> dict:
    """The physical parameters of ``eff`` at its knob (what goes into truth.json)."""
    T = s.T
    k = eff.knob
    fsae = s.variant.kind == "fsae"
    f = eff.fixed
    Fz0 = T[ty.FZ0]
    if eff.name == "temperature":
        # the window's curvature from its steepest slope over the session's temperatures:
        # |dW/dT| <= SLOPE (0.15-0.6 %/K) at the farthest surface temperature D from TOPT
        slope = max(lerp(0.0015, 0.006, k), 0.0003)
        twid = 50.0
        tcw = float(min(slope * twid * twid / (2.0 * f["D"]), 0.35))
        return {"T_opt_degC": f["Topt"], "grip_loss_at_window_scale": tcw,
                "window_scale_degC": twid, "max_slope_per_K": slope,
                "farthest_surface_T_from_opt_K": f["D"],
                "stiffness_loss_per_K_bulk": max(lerp(0.001, 0.003, k), 0.0002),
                "T_nom_degC": s.Tnom, "side": eff.kind}  # fmt: skip
    if eff.name == "pressure":
        if eff.kind == "leak":
            return {"mode": "leak", "loss_fraction_at_end": float(np.clip(lerp(0.05, 0.2, k), 0.01, 0.22)),
                    "time_constant_s": f["tau"]}  # fmt: skip
        if eff.kind == "sealed":
            return {"mode": "sealed", "gas_conductance_factor": max(lerp(0.7, 2.5, k), 0.2)}
        return {"mode": "set points + sealed gas between re-inflations"}
    if eff.name == "relaxation":
        lo, hi = (0.12, 0.35) if fsae else (0.3, 0.65)
        sa = max(lerp(lo, hi, k), 0.03)
        return {"sigma_alpha_m_at_FZ0": sa, "sigma_kappa_m_at_FZ0": sa * f["rk"],
                "load_exponent": f["nsig"], "share_when_sliding": f["smin"]}  # fmt: skip
    if eff.name == "time_delay":
        return {
            "transport_delay_s": max(lerp(0.004, 0.025, k), 0.0005),
            "filter": "Butterworth order 2",
            "cutoff_Hz": float(np.clip(lerp(25.0, 8.0, k), 6.0, 60.0)),
        }
    if eff.name == "offset":
        Kya0 = -ty.evaluate(T, Fz0, 0.0, 1e-4)["Fy"] / 1e-4
        Kyg0 = -ty.evaluate(T, Fz0, 0.0, 0.0, 1e-3)["Fy"] / 1e-3
        scale = Fz0 / 1100.0
        fps = max(lerp(0.005, 0.02, k), 0.0005) * f["s_ps"]
        fcon = max(lerp(0.003, 0.015, k), 0.0003) * f["s_con"]
        return {
            "ply_steer_Fy_over_Fz0": fps,
            "ply_steer_residual_alpha_rad": fps * Fz0 / Kya0,
            "conicity_Fy_over_Fz0": fcon,
            "conicity_residual_gamma_rad": fcon * Fz0 / Kyg0,
            "loadcell_zero_Fx_N": f["s_zx"] * max(lerp(2.0, 12.0, k), 0.5) * scale,
            "loadcell_zero_Fy_N": f["s_zy"] * max(lerp(2.0, 15.0, k), 0.5) * scale,
            "loadcell_zero_Mz_Nm": f["s_zm"] * max(lerp(0.2, 1.0, k), 0.05) * scale,
        }
    if eff.name == "drift":
        return {
            "grip_loss_at_end": max(lerp(0.015, 0.06, k), 0.002),
            "stiffening_per_grip_loss": f["wst"],
            "driver": "sliding energy",
        }
    if eff.name == "speed":
        return {"sliding_speed_exponent": float(np.clip(lerp(0.4, 1.0, k), 0.05, 1.0)),
                "law": "mu_k = mu_s (RINF + (1-RINF) exp(-V_eff |s| / VC)), "
                       "V_eff = VREF (V/VREF)^lambda (lambda = 0: no speed dependence)",
                "RINF": float(T[ty.RINF]), "VC_m_s": float(T[ty.VC]),
                "VREF_m_s": float(T[ty.VREF])}  # fmt: skip
    if eff.name == "camber":
        return {
            "camber_stiffness_over_Fz_per_rad": s.variant.targets["Kyg_rel"],
            "equivalent_slip_per_sin_gamma": float(T[ty.CAMK]),
            "pressure_shift_per_sin_gamma": float(T[ty.PGAM]),
            "spin_slip_factor": float(T[ty.EGAM]),
            "Mx_QSX2": float(T[ty.QSX2]),
        }
    if eff.name == "combined_slip":
        return {
            "coupling": "brush friction ellipse on the resultant slip",
            "mu_x_over_mu_y": float(T[ty.RX]),
        }
    if eff.name == "sidewall_contact":
        d0 = ty.deflection(T, Fz0, T[ty.P0])
        return {
            "force_drop": lerp(0.06, 0.18, k),
            "deflection_onset_m": 1.5 * d0,
            "deflection_ramp_m": 0.25 * d0,
            "alpha_onset_rad_at_onset": f["a0"],
            "alpha_ramp_rad": math.radians(3.0),
        }
    raise KeyError(eff.name)


def apply_effect(s: Session, eff: Effect, E: np.ndarray, post: dict) -> None:
    """Switch ``eff`` on in E / post at its knob."""
    P = effect_params(s, eff)
    if eff.name == "temperature":
        E[sim.E_TEMP_ON] = 1.0
        E[sim.E_TOPT] = P["T_opt_degC"]
        E[sim.E_TCW] = P["grip_loss_at_window_scale"]
        E[sim.E_TWID] = P["window_scale_degC"]
        E[sim.E_TKS] = P["stiffness_loss_per_K_bulk"]
    elif eff.name == "pressure":
        if eff.kind == "leak":
            E[sim.E_PMODE] = 2.0
            E[sim.E_LEAK_F] = P["loss_fraction_at_end"]
            E[sim.E_LEAK_TAU] = P["time_constant_s"]
        elif eff.kind == "sealed":
            E[sim.E_PMODE] = 1.0
            E[sim.E_HBG] *= P["gas_conductance_factor"]
        else:  # recorded: the pressure dependence itself is the missing physics
            E[sim.E_PMODE] = 1.0
            E[sim.E_PCONST] = 0.0
    elif eff.name == "relaxation":
        E[sim.E_RELAX_ON] = 1.0
        E[sim.E_SIGA0] = P["sigma_alpha_m_at_FZ0"]
        E[sim.E_SIGK0] = P["sigma_kappa_m_at_FZ0"]
        E[sim.E_NSIG] = P["load_exponent"]
        E[sim.E_SMIN] = P["share_when_sliding"]
    elif eff.name == "time_delay":
        post["delay"] = {"tau": P["transport_delay_s"], "fc": P["cutoff_Hz"]}
    elif eff.name == "offset":
        E[sim.E_OFF_ON] = 1.0
        E[sim.E_PLY_ALPHA] = P["ply_steer_residual_alpha_rad"]
        E[sim.E_CON_GAMMA] = P["conicity_residual_gamma_rad"]
        post["zeros"] = {"Fx": P["loadcell_zero_Fx_N"], "Fy": P["loadcell_zero_Fy_N"],
                         "Mz": P["loadcell_zero_Mz_Nm"]}  # fmt: skip
    elif eff.name == "drift":
        E[sim.E_WEAR_ON] = 1.0
        E[sim.E_WEAR_RATE] = P["grip_loss_at_end"] / s.fixed_energy
        E[sim.E_WEAR_STIFF] = P["stiffening_per_grip_loss"]
    elif eff.name == "speed":
        E[sim.E_SPEED_ON] = 1.0
        E[sim.E_SPEED_LAM] = P["sliding_speed_exponent"]
    elif eff.name == "camber":
        E[sim.E_CAMBER_ON] = 1.0
    elif eff.name == "combined_slip":
        E[sim.E_COMB_ON] = 1.0
    elif eff.name == "sidewall_contact":
        E[sim.E_SW_ON] = 1.0
        E[sim.E_SW_D] = P["force_drop"]
        E[sim.E_SW_DC] = P["deflection_onset_m"]
        E[sim.E_SW_WD] = P["deflection_ramp_m"]
        E[sim.E_SW_A0] = P["alpha_onset_rad_at_onset"]
        E[sim.E_SW_WA] = P["alpha_ramp_rad"]


def base_E(s: Session) -> np.ndarray:
    """Everything the tyre always has, with every named effect off (camber and combined slip
    are part of the tyre unless the case names them)."""
    E = s.E_base.copy()
    names = {e.name for e in s.effects}
    E[sim.E_CAMBER_ON] = 0.0 if "camber" in names else 1.0
    E[sim.E_COMB_ON] = 0.0 if "combined_slip" in names else 1.0
    E[sim.E_PCONST] = 1.0 if any(e.name == "pressure" and e.kind == "recorded"
                                 for e in s.effects) else 0.0  # fmt: skip
    return E


def run(s: Session, active: list) -> dict:
    """Simulate with the effects in ``active`` on; returns sim dict + 'meas' (N, 6)."""
    E = base_E(s)
    post = {}
    for eff in active:
        apply_effect(s, eff, E, post)
    r = sim.simulate(s.T, E, s.prog)
    r["meas"] = sim.post(r, s.prog.Fz, post.get("delay"), post.get("zeros"))
    return r


def ms_of(a: dict, b: dict) -> float:
    d = a["meas"][:, :2] - b["meas"][:, :2]
    return float(np.mean(np.sum(d * d, axis=1)))


def measure(s: Session) -> tuple[dict, dict]:
    """(all-effects run, {effect name: ms_N2})."""
    full = run(s, s.effects)
    ms = {}
    for e in s.effects:
        wo = run(s, [x for x in s.effects if x is not e])
        ms[e.name] = ms_of(full, wo)
    return full, ms


# ------------------------------------------------------------------------------------------
# case set-up
# ------------------------------------------------------------------------------------------
def _rng(case: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(case.encode()), 7])


def _noise(rng, kind: str) -> dict:
    if kind == "fsae":
        F = rng.uniform(8.0, 14.0)
        return {"Fx_N": F * rng.uniform(0.9, 1.1), "Fy_N": F, "Fz_N": rng.uniform(8.0, 14.0),
                "Mx_Nm": rng.uniform(0.8, 1.5), "My_Nm": rng.uniform(0.2, 0.4),
                "Mz_Nm": rng.uniform(0.4, 0.8), "load_topic_N": rng.uniform(3.0, 6.0),
                "alpha_rad": math.radians(rng.uniform(0.01, 0.02)),
                "kappa": rng.uniform(0.0002, 0.0004), "gamma_rad": math.radians(0.01),
                "pressure_Pa": rng.uniform(250.0, 500.0), "temperature_degC":
                rng.uniform(0.3, 0.8), "temperature_lag_s": rng.uniform(0.3, 0.6),
                "velocity_m_s": rng.uniform(0.02, 0.05)}  # fmt: skip
    F = rng.uniform(18.0, 30.0)
    return {"Fx_N": F * rng.uniform(0.9, 1.1), "Fy_N": F, "Fz_N": rng.uniform(20.0, 35.0),
            "Mx_Nm": rng.uniform(2.0, 4.0), "My_Nm": rng.uniform(0.5, 1.0),
            "Mz_Nm": rng.uniform(1.0, 2.5), "load_topic_N": rng.uniform(10.0, 20.0),
            "alpha_rad": math.radians(rng.uniform(0.01, 0.02)),
            "kappa": rng.uniform(0.0002, 0.0004), "gamma_rad": math.radians(0.01),
            "pressure_Pa": rng.uniform(500.0, 1000.0), "temperature_degC":
            rng.uniform(0.3, 0.8), "temperature_lag_s": rng.uniform(0.3, 0.6),
            "velocity_m_s": rng.uniform(0.02, 0.05)}  # fmt: skip


def setup(case: str, seed: int, minutes: float = 8.0, tyre: str | None = None) -> Session:
    if case not in CASES:
        raise SystemExit(f"unknown case {case!r}; --list shows the cases")
    rng = _rng(case, seed)
    vname = rng.choice(list(ty.VARIANTS), p=[0.4, 0.3, 0.3])
    variant = ty.VARIANTS[str(tyre or vname)]
    T = ty.tyre_vector(variant)
    tir_nom, fit_rep = ft.get_fitted(variant)
    kind = variant.kind
    # ---- effects of the case
    effects: list[Effect] = []
    temp_side = None
    if case.startswith("heat_"):
        side = case[5:]
        if side == "recorded":
            side = str(rng.choice(["below", "above", "cross"]))
        temp_side = side
        effects.append(Effect("temperature", case != "heat_recorded", rng.uniform(0.5, 1.0),
                              kind=side))  # fmt: skip
    elif case == "pressure_sealed":
        effects.append(Effect("pressure", True, rng.uniform(0.4, 1.0), kind="sealed"))
    elif case == "pressure_leak":
        effects.append(Effect("pressure", True, rng.uniform(0.2, 1.0), kind="leak",
                              fixed={"tau": float(rng.uniform(150.0, 3000.0))}))  # fmt: skip
    elif case == "pressure_recorded":
        effects.append(Effect("pressure", False, 1.0, kind="recorded", sizable=False))
    elif case == "wear":
        effects.append(Effect("drift", True, rng.uniform(0.3, 1.0)))
    elif case == "relaxation":
        effects.append(Effect("relaxation", False, rng.uniform(0.2, 1.0)))
    elif case == "delay":
        effects.append(Effect("time_delay", False, rng.uniform(0.2, 1.0)))
    elif case == "offset":
        effects.append(Effect("offset", False, rng.uniform(0.3, 1.0)))
    elif case == "speed":
        effects.append(Effect("speed", False, rng.uniform(0.4, 1.0)))
    elif case == "camber":
        effects.append(Effect("camber", False, 1.0, sizable=False))
    elif case == "combined":
        effects.append(Effect("combined_slip", False, 1.0, sizable=False))
    elif case == "sidewall":
        effects.append(Effect("sidewall_contact", False, rng.uniform(0.3, 1.0)))
    elif case.startswith("multi"):
        k = 3 if case == "multi3" else 2
        names = list(rng.choice(MULTI_POOL, size=k, replace=False))
        for i, n in enumerate(names):
            knob = rng.uniform(0.75, 1.0) if i == 0 else rng.uniform(0.25, 0.6)
            if n == "temperature":
                temp_side = str(rng.choice(["below", "above", "cross"]))
                effects.append(Effect(n, True, knob, kind=temp_side))
            elif n == "pressure":
                pk = str(rng.choice(["sealed", "leak"]))
                effects.append(
                    Effect(n, True, knob, kind=pk, fixed={"tau": float(rng.uniform(150.0, 3000.0))})
                )
            else:
                effects.append(Effect(n, n not in ("offset", "relaxation", "time_delay",
                                                    "speed"), knob))  # fmt: skip
    for e in effects:  # random choices not scaled by the knob
        e.fixed.setdefault("rk", float(rng.uniform(0.5, 0.8)))
        e.fixed.setdefault("nsig", float(rng.uniform(0.3, 0.6)))
        e.fixed.setdefault("smin", float(rng.uniform(0.2, 0.4)))
        for key in ("s_ps", "s_con", "s_zx", "s_zy", "s_zm"):
            e.fixed.setdefault(key, float(rng.choice([-1.0, 1.0])))
        e.fixed.setdefault("wst", float(rng.uniform(0.3, 1.0)))
        e.fixed.setdefault("a0", math.radians(float(rng.uniform(8.0, 11.0))))
    names = {e.name for e in effects}
    pressure_concealed = any(e.name == "pressure" and e.concealed for e in effects)
    # ---- topics
    if case.startswith("null"):
        rec_p = bool(rng.random() < 0.6)
        rec_T = bool(rng.random() < 0.5)
    else:
        rec_p = not pressure_concealed
        rec_T = case == "heat_recorded"
    topics = {"pressure": rec_p, "temperature": rec_T, "velocity": True}
    # ---- programme
    speeds = None
    if "speed" in names:
        speeds = (T[ty.VREF], 25.0 / 3.6, float(rng.choice([55.0, 65.0])) / 3.6)
    prog = pg.build(rng, variant, T, minutes, single_pressure=not rec_p, speeds=speeds,
                    other_speed_block=bool(rng.random() < 0.4),
                    sidewall=case == "sidewall")  # fmt: skip
    # ---- thermal model and start state
    th = {k: v * float(rng.uniform(0.8, 1.25)) for k, v in THERMAL[kind].items()}
    th["ETAR"] = 1.0
    Ta = float(rng.uniform(15.0, 30.0))
    prewarm = float(rng.uniform(15.0, 45.0)) if rng.random() < 0.35 else 0.0
    E_base = sim.evec(**th, TA=Ta, T0S=Ta + prewarm, T0B=Ta + prewarm,
                      T0G=Ta + 0.7 * prewarm, TNOM=Ta + prewarm,
                      T_END=minutes * 60.0)  # fmt: skip
    noise = _noise(rng, kind)
    s = Session(case=case, seed=seed, minutes=minutes, variant=variant, T=T, tir=None,
                tir_nominal=tir_nom, fit_report=fit_rep, prog=prog, E_base=E_base,
                effects=effects, topics=topics, noise=noise, imperfections=[],
                Tnom=Ta + prewarm)  # fmt: skip
    s.rng = rng
    s.fixed_energy = 1.0
    if temp_side is not None:
        _place_temperature(s, temp_side)
    # sliding energy of the session (wear is sized on it)
    base = run(s, [])
    s.fixed_energy = float(np.sum(base["Psl"]) * sim.DT)
    s.base_run = base
    # ---- model.tir: the tyre as characterised, lacking what the case leaves out
    upd = {"NOMTEMP": max(s.Tnom, 1.0)}
    if "camber" in names:
        upd.update({n: 0.0 for n in ft.CAMBER_TERMS})
    if "combined_slip" in names:
        upd.update(ft.COMBINED_ZERO)
    if any(e.name == "pressure" and e.kind == "recorded" for e in effects):
        upd.update({n: 0.0 for n in ft.PRESSURE_TERMS})
    s.tir = tir_nom.with_params(upd)
    # ---- imperfections (nulls)
    s.imperfections = _imperfections(case, rng, noise)
    return s


def _place_temperature(s: Session, side: str) -> None:
    """Choose ambient, start state and grip optimum so that the tyre runs on ``side`` of its
    optimum (below / above / crossing it), from the session's own thermal trajectory (the
    thermal model is linear in the temperatures: simulate relative to ambient, then shift)."""
    rng = s.rng
    lo, hi = (COMPOUND_SOFT if side == "above" else COMPOUND)[s.variant.kind]
    if side == "cross":  # wherever the session's surface temperature passes
        lo, hi = 45.0, hi
    E = s.E_base
    pre = {"above": float(rng.uniform(30.0, 50.0)), "below": float(rng.uniform(0.0, 10.0)),
           "cross": float(rng.uniform(0.0, 5.0))}[side]  # fmt: skip
    u_target = float(rng.uniform(0.0, 1.0))
    for key, val in (("TA", 0.0), ("T0S", pre), ("T0B", pre), ("T0G", 0.7 * pre),
                     ("TNOM", pre)):  # fmt: skip
        E[getattr(sim, "E_" + key)] = val
    dTs = sim.simulate(s.T, E, s.prog)["Ts"]  # relative to ambient
    after = dTs[int(20.0 / sim.DT) :]
    if side == "below":  # optimum above the hottest surface temperature
        rel = float(np.percentile(dTs, 99.0)) + lerp(12.0, 30.0, u_target)
        Ta = float(np.clip(lerp(lo + 10.0, hi, u_target) - rel, 10.0, 32.0))
    elif side == "above":  # pre-warmed, optimum below the coolest running temperature
        rel = float(np.percentile(after, 3.0)) - lerp(3.0, 10.0, u_target)
        Ta = float(np.clip(lerp(lo, hi, u_target) - rel, 15.0, 35.0))
    else:  # cold start, optimum crossed: at a 35-60 % quantile of the surface temperature
        rel = max(float(np.percentile(dTs, lerp(15.0, 40.0, u_target))), pre + 8.0)
        Ta = float(np.clip(lerp(lo, hi, u_target) - rel, 10.0, 35.0))
    Topt = Ta + rel
    for key, val in (("TA", Ta), ("T0S", Ta + pre), ("T0B", Ta + pre),
                     ("T0G", Ta + 0.7 * pre), ("TNOM", Ta + pre)):  # fmt: skip
        E[getattr(sim, "E_" + key)] = val
    s.Tnom = Ta + pre
    lo_T, hi_T = np.percentile(dTs, [0.5, 99.5]) + Ta
    for e in s.effects:
        if e.name == "temperature":
            e.fixed["Topt"] = Topt
            e.fixed["D"] = float(max(abs(lo_T - Topt), abs(hi_T - Topt), 5.0))


def _imperfections(case, rng, noise) -> list:
    if not case.startswith("null"):
        return []
    n = int(case.split("_")[1])
    kinds = {
        1: ["gain"],
        2: ["spikes"],
        3: ["dropouts"],
        4: ["zero_wander"],
        5: ["gain", "spikes", "zero_wander"],
        6: ["dropouts", "spikes", "gain"],
    }[n]
    out = []
    for k in kinds:
        if k == "gain":
            out.append(
                {
                    "kind": "loadcell_gain",
                    "Fx": float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.03)),
                    "Fy": float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.03)),
                    "Mz": float(rng.uniform(-0.02, 0.02)),
                }
            )
        elif k == "spikes":
            out.append({"kind": "spikes", "rate_per_sample": 1.0 / 5000.0,
                        "size_in_sigmas": [5.0, 30.0]})  # fmt: skip
        elif k == "dropouts":
            topics = ["slip", "measured_forces", "load", "velocity"]
            chosen = [t for t in topics if rng.random() < 0.6] or ["slip"]
            out.append(
                {
                    "kind": "dropouts",
                    "topics": chosen,
                    "count": int(rng.integers(6, 20)),
                    "gap_s": [0.05, 0.5],
                }
            )
        elif k == "zero_wander":
            out.append({"kind": "zero_wander", "sigma_N": float(rng.uniform(2.0, 6.0)),
                        "time_constant_s": float(rng.uniform(40.0, 150.0)),
                        "channels": ["Fx", "Fy"]})  # fmt: skip
    return out


# ------------------------------------------------------------------------------------------
# sizing
# ------------------------------------------------------------------------------------------
def noise_var(s: Session) -> float:
    return s.noise["Fx_N"] ** 2 + s.noise["Fy_N"] ** 2


def size_effects(s: Session) -> tuple[dict, dict]:
    """Adjust the knobs: single effects >= ~2x the noise variance (and not absurd), multi
    cases with the first effect >= 2x (target 2.5x) the ms of the others. Returns
    (all-effects run, ms)."""
    nv = noise_var(s)
    sizable = [e for e in s.effects if e.sizable]
    full, ms = measure(s)
    if not sizable:
        return full, ms
    if len(s.effects) == 1:
        e = s.effects[0]
        for _ in range(5):
            m = ms[e.name]
            if m < 2.0 * nv and e.knob < 1.0:
                e.knob = min(1.0, e.knob * math.sqrt(2.5 * nv / max(m, 1e-9)) + 0.1)
            elif m > 120.0 * nv and e.knob > 0.0:
                e.knob = max(0.0, e.knob - 0.35)
            else:
                break
            full, ms = measure(s)
        return full, ms
    first, others = s.effects[0], s.effects[1:]
    for _ in range(3):  # the strongest not absurd either
        if ms[first.name] > 150.0 * nv and first.knob > 0.0:
            first.knob = max(0.0, first.knob - 0.4)
            full, ms = measure(s)
    for _ in range(8):
        worst = max(others, key=lambda e: ms[e.name])
        weak = min(others, key=lambda e: ms[e.name])
        if ms[first.name] >= 2.2 * ms[worst.name] and ms[weak.name] >= 0.8 * nv:
            break
        if ms[weak.name] < 0.8 * nv and weak.knob < 1.0:
            weak.knob = min(1.0, weak.knob + 0.3)
        if ms[first.name] < 2.2 * ms[worst.name]:
            if first.knob < 1.2:  # the strongest may reach a little past the usual range
                first.knob = min(1.2, first.knob + 0.2)
            ratio = ms[first.name] / max(ms[worst.name], 1e-9)
            worst.knob = max(-0.45, worst.knob - max(0.15, 0.5 * (1.0 - ratio / 2.5)))
        full, ms = measure(s)
    return full, ms


# ------------------------------------------------------------------------------------------
# recording, twin, outputs
# ------------------------------------------------------------------------------------------
def _change_index(x: np.ndarray, tol: float) -> np.ndarray:
    """Indices where x moved more than tol from the last kept value (first always kept)."""
    keep = [0]
    last = x[0]
    for i in range(1, len(x)):
        if abs(x[i] - last) > tol:
            keep.append(i)
            last = x[i]
    return np.array(keep, int)


def _dropout_mask(rng, n, count, gap):
    m = np.ones(n, bool)
    for _ in range(count):
        L = int(round(rng.uniform(*gap) / sim.DT))
        i0 = int(rng.integers(100, n - L - 100))
        m[i0 : i0 + L] = False
    return m


def build_outputs(s: Session, full: dict, ms: dict) -> dict:
    rng = np.random.default_rng([s.seed, zlib.crc32(s.case.encode()), 99])
    prog = s.prog
    n = len(prog.t)
    t = prog.t
    nz = s.noise
    true_meas = full["meas"]
    # dropouts
    slip_keep = np.ones(n, bool)
    drop = {}
    for imp in s.imperfections:
        if imp["kind"] == "dropouts":
            for topic in imp["topics"]:
                drop[topic] = _dropout_mask(rng, n, max(1, imp["count"] // len(imp["topics"])),
                                            imp["gap_s"])  # fmt: skip
    if "slip" in drop:
        slip_keep = drop["slip"]
    # ---- twin: true inputs and forces, every channel, at the slip stamps
    ks = np.flatnonzero(slip_keep)
    twin = {
        "slip": (t[ks], np.stack([prog.kappa, prog.alpha, prog.gamma], axis=1)[ks]),
        "measured_forces": (t[ks], true_meas[ks]),
    }
    for ch, arr, tol in (
        ("load", prog.Fz, 1e-3),
        ("velocity", prog.V, 1e-5),
        ("pressure", full["p"], 0.5),
        ("temperature", full["Ts"], 0.002),
    ):
        sub = arr[ks]
        idx = _change_index(sub, tol)
        twin[ch] = (t[ks][idx], sub[idx])
    # ---- recording
    meas = true_meas.copy()
    sig = np.array([nz["Fx_N"], nz["Fy_N"], nz["Fz_N"], nz["Mx_Nm"], nz["My_Nm"], nz["Mz_Nm"]])
    for imp in s.imperfections:
        if imp["kind"] == "loadcell_gain":
            meas[:, 0] *= 1.0 + imp["Fx"]
            meas[:, 1] *= 1.0 + imp["Fy"]
            meas[:, 5] *= 1.0 + imp["Mz"]
        elif imp["kind"] == "zero_wander":
            a = math.exp(-sim.DT / imp["time_constant_s"])
            for c in (0, 1):
                w = rng.normal(0.0, imp["sigma_N"] * math.sqrt(1 - a * a), n)
                z = np.empty(n)
                z[0] = rng.normal(0.0, imp["sigma_N"])
                for i in range(1, n):
                    z[i] = a * z[i - 1] + w[i]
                meas[:, c] += z
    meas += rng.normal(0.0, 1.0, meas.shape) * sig
    for imp in s.imperfections:
        if imp["kind"] == "spikes":
            hit = rng.random(n) < imp["rate_per_sample"]
            idx = np.flatnonzero(hit)
            for i in idx:
                c = int(rng.integers(0, 2))
                meas[i, c] += rng.choice([-1, 1]) * rng.uniform(5, 30) * sig[c]
            imp["count"] = int(len(idx))
    f_keep = slip_keep & drop.get("measured_forces", np.ones(n, bool))
    slip_noisy = np.stack(
        [
            prog.kappa + rng.normal(0, nz["kappa"], n),
            prog.alpha + rng.normal(0, nz["alpha_rad"], n),
            prog.gamma + rng.normal(0, nz["gamma_rad"], n),
        ],
        axis=1,
    )
    rec = {"slip": (t[ks], slip_noisy[ks]), "measured_forces": (t[f_keep], meas[f_keep])}
    li = np.arange(0, n, 2)
    li = li[drop.get("load", np.ones(n, bool))[li]]
    rec["load"] = (t[li], prog.Fz[li] + rng.normal(0, nz["load_topic_N"], len(li)))
    vi = np.arange(0, n, 10)
    vi = vi[drop.get("velocity", np.ones(n, bool))[vi]]
    rec["velocity"] = (t[vi], prog.V[vi] + rng.normal(0, nz["velocity_m_s"], len(vi)))
    si = np.arange(0, n, 10)
    if s.topics["pressure"]:
        rec["pressure"] = (t[si], full["p"][si] + rng.normal(0, nz["pressure_Pa"], len(si)))
    if s.topics["temperature"]:
        a = math.exp(-sim.DT / nz["temperature_lag_s"])
        Tm = np.empty(n)
        Tm[0] = full["Ts"][0]
        Ts = full["Ts"]
        for i in range(1, n):
            Tm[i] = a * Tm[i - 1] + (1 - a) * Ts[i]
        rec["temperature"] = (t[si], Tm[si] + rng.normal(0, nz["temperature_degC"], len(si)))
    return {"recording": rec, "twin": twin}


def describe(s: Session, full: dict, ms: dict) -> dict:
    eff_list = []
    for e in s.effects:
        P = effect_params(s, e)
        eff_list.append({"name": e.name, "concealed": bool(e.concealed),
                         "ms_N2": ms[e.name], "detail": _detail(s, e, P, full),
                         "parameters": P})  # fmt: skip
    eff_list.sort(key=lambda d: -d["ms_N2"])
    prog = s.prog
    kinds = prog.kind
    text = (f"TTC-like rig session, {s.minutes:g} min at 100 Hz: "
            f"{int(np.sum(np.diff(np.r_[0, kinds == 2]) == 1))} lateral sweeps (amplitude "
            f"{np.degrees(np.max(np.abs(prog.alpha[kinds == 2]))):.1f} deg), "
            f"{int(np.sum(np.diff(np.r_[0, kinds == 3]) == 1))} drive/brake sweeps, loads "
            f"{sorted(set(np.round(prog.Fz[kinds >= 2]).astype(int).tolist()))} N, pressures "
            f"{sorted(set(np.round(prog.pset / 1000).astype(int).tolist()))} kPa, cambers "
            f"{sorted(set(np.round(np.degrees(prog.gamma[kinds >= 2])).astype(int).tolist()))}"
            f" deg, speeds "
            f"{sorted(set(round(u.V * 3.6) for u in prog.units))} km/h; "
            f"no pauses between blocks.\n" + prog.text)  # fmt: skip
    return eff_list, text


def _detail(s, e, P, full) -> str:
    if e.name == "temperature":
        Ts = full["Ts"]
        return (f"tread surface {Ts.min():.0f}..{Ts.max():.0f} degC (median "
                f"{np.median(Ts):.0f}), bulk {full['Tb'].min():.0f}..{full['Tb'].max():.0f} "
                f"degC, grip optimum {P['T_opt_degC']:.0f} degC ({e.kind}); model.tir is the "
                f"tyre at {s.Tnom:.0f} degC")  # fmt: skip
    if e.name == "pressure":
        p = full["p"]
        return (f"{P['mode']}: gauge pressure {p.min() / 1000:.1f}..{p.max() / 1000:.1f} kPa "
                f"(start {p[0] / 1000:.1f}); gas {full['Tg'].min():.0f}.."
                f"{full['Tg'].max():.0f} degC")  # fmt: skip
    if e.name == "drift":
        return f"grip lost to wear by the end: {100 * full['wear'][-1]:.2f} %"
    if e.name == "relaxation":
        return (
            f"slip lag over sigma_alpha {P['sigma_alpha_m_at_FZ0']:.2f} m at FZ0 "
            f"(x (Fz/FZ0)^{P['load_exponent']:.2f}, shorter when sliding)"
        )
    if e.name == "time_delay":
        return (f"force channels delayed {1000 * P['transport_delay_s']:.1f} ms and filtered "
                f"at {P['cutoff_Hz']:.1f} Hz (group delay ~{1000 * 0.225 / P['cutoff_Hz']:.0f}"
                f" ms)")  # fmt: skip
    if e.name == "offset":
        return (
            f"ply-steer {100 * P['ply_steer_Fy_over_Fz0']:+.2f} % Fz0, conicity "
            f"{100 * P['conicity_Fy_over_Fz0']:+.2f} % Fz0, load-cell zeros Fx "
            f"{P['loadcell_zero_Fx_N']:+.1f} N, Fy {P['loadcell_zero_Fy_N']:+.1f} N"
        )
    if e.name == "speed":
        return (
            f"sliding friction follows the sliding speed (exponent "
            f"{P['sliding_speed_exponent']:.2f}); blocks at "
            f"{sorted(set(round(u.V * 3.6) for u in s.prog.units))} km/h"
        )
    if e.name == "camber":
        return "camber thrust, pressure shift and spin of the inclined tyre; model.tir has none"
    if e.name == "combined_slip":
        return "brush friction ellipse couples the slips; model.tir has no combined weighting"
    if e.name == "sidewall_contact":
        return (
            f"Fy drop {100 * P['force_drop']:.0f} % beyond the peak when the deflection "
            f"exceeds {1000 * P['deflection_onset_m']:.1f} mm (low pressure, high load)"
        )
    return ""


def generate(
    case: str,
    seed: int,
    outdir: str,
    minutes: float = 8.0,
    quiet: bool = False,
    tyre: str | None = None,
):
    t_start = time.time()
    out = Path(outdir)
    if out.exists():
        raise SystemExit(f"{out} exists; choose a new OUTDIR")
    s = setup(case, seed, minutes, tyre)
    full, ms = size_effects(s)
    if not s.effects:
        full = run(s, [])
    chans = build_outputs(s, full, ms)
    effects, prog_text = describe(s, full, ms)
    # model fit on this session: model.tir (nominal) against the nominal brush at the
    # session's true inputs (steady state, no effects, camber and combined slip included)
    pr = s.prog
    nomb = ty.evaluate(s.T, pr.Fz, pr.kappa, pr.alpha, pr.gamma, pr.V, full["p"])
    o = TireModel(s.tir_nominal).evaluate(pr.Fz, pr.kappa, pr.alpha, pr.gamma, pr.V,
                                           full["p"], full=False)  # fmt: skip
    fit_rms = {c: float(np.sqrt(np.mean((getattr(o, c) - nomb[c]) ** 2)))
               for c in ("Fx", "Fy", "Mz")}  # fmt: skip
    out.mkdir(parents=True)
    write_bag(out / "recording", {PREFIX: chans["recording"]})
    write_bag(out / "twin", {PREFIX: chans["twin"]})
    write_tir(s.tir, out / "model.tir")
    nz = s.noise
    truth = {
        "generator": NAME, "case": case, "seed": int(seed), "minutes": float(minutes),
        "wheels": [PREFIX], "null": not effects, "effects": effects,
        "imperfections": s.imperfections,
        "tyre": f"{s.variant.name}: {s.variant.description}; model.tir fitted by least "
                f"squares to the nominal brush ({ft.fitted_path(s.variant).name})",
        "noise": {**nz, "force_noise_variance_N2": nz["Fx_N"] ** 2 + nz["Fy_N"] ** 2},
        "programme": prog_text,
        "description": _description(s, effects),
        "topics": s.topics,
        "model_fit_rms_N": {"this_session": fit_rms, "fit_grid": s.fit_report},
        "generation_s": round(time.time() - t_start, 2),
    }  # fmt: skip
    (out / "truth.json").write_text(json.dumps(truth, indent=1, default=_json_default))
    if not quiet:
        nv = truth["noise"]["force_noise_variance_N2"]
        print(f"{NAME} {case} seed {seed}: tyre {s.variant.name}, {len(pr.t)} samples, "
              f"noise var {nv:.0f} N2, model fit rms Fx {fit_rms['Fx']:.1f} Fy "
              f"{fit_rms['Fy']:.1f} N")  # fmt: skip
        for e in effects:
            print(f"  {e['name']:<16} ms {e['ms_N2']:10.0f} N2 = {e['ms_N2'] / nv:6.1f} x "
                  f"noise  {e['detail']}")  # fmt: skip
        if not effects:
            print(f"  null; imperfections: {[i['kind'] for i in s.imperfections]}")
        print(f"  written to {out} in {time.time() - t_start:.1f} s")
    return truth


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _description(s: Session, effects: list) -> str:
    v = s.variant
    parts = [f"A {v.description} runs a TTC-like programme on a flat-belt rig at "
             f"{s.T[ty.VREF] * 3.6:.0f} km/h (ambient {s.E_base[sim.E_TA]:.0f} degC, tyre "
             f"starting at {s.E_base[sim.E_T0S]:.0f} degC). Its forces come from a 2-D brush "
             "model (parabolic-like contact pressure, adhesion and sliding zones, static/"
             "sliding friction, carcass compliance, camber thrust and spin)."]  # fmt: skip
    for e in effects:
        parts.append(f"{e['name']}: {e['detail']}.")
    if not effects:
        parts.append("Nothing is missing from model.tir; only sensor noise and the listed "
                     "imperfections separate the recording from it.")  # fmt: skip
    if s.imperfections:
        parts.append("Imperfections: " + ", ".join(i["kind"] for i in s.imperfections) + ".")
    return " ".join(parts)
