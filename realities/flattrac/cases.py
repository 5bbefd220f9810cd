"""The cases: which physics each one carries, how it is drawn per seed, and its sizes.

``build(case, seed, minutes)`` returns a :class:`Plan`: the session (true inputs and every
physical parameter), the model.tir tyre, what the recording carries, and the noise.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from . import physics as ph
from . import programme as pg
from .tyre import BaseTyre

DEG = np.pi / 180.0

SINGLE = {
    "heat_below": "temperature", "heat_above": "temperature", "heat_cross": "temperature",
    "heat_recorded": "temperature", "pressure_sealed": "pressure", "pressure_leak": "pressure",
    "pressure_recorded": "pressure", "wear": "drift", "relaxation": "relaxation",
    "delay": "time_delay", "offset": "offset", "speed": "speed", "camber": "camber",
    "combined": "combined_slip", "sidewall": "sidewall_contact",
}  # fmt: skip
MULTI = {"multi2_a": 2, "multi2_b": 2, "multi3": 3}
NULLS = {
    "null_1": ("gain",),
    "null_2": ("spikes",),
    "null_3": ("dropouts",),
    "null_4": ("zero_walk",),
    "null_5": ("gain", "spikes", "dropouts"),
    "null_6": ("gain", "spikes", "dropouts", "zero_walk"),
}
CASES = [*SINGLE, *MULTI, *NULLS]
MULTI_POOL = ("temperature", "pressure", "offset", "relaxation", "time_delay", "drift", "speed")


@dataclass
class Plan:
    case: str
    seed: int
    minutes: float
    tyre: BaseTyre
    prog: pg.Programme
    session: ph.Session
    model_tir: object  # TireModel written as model.tir
    effects: list  # effect names (INTERFACE words) in the session
    concealed: dict  # effect -> bool
    record_pressure: bool
    record_temperature: bool
    noise: dict
    imperfections: list
    side: str = ""  # temperature: below / above / cross
    notes: dict = field(default_factory=dict)


def _rng(case: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(case.encode())])


# ------------------------------------------------------------------------------ drawing
def _thermal(rng, tyre: BaseTyre, start: str, strong_gas: bool = False) -> dict:
    S = tyre.size
    T_amb = float(rng.uniform(20.0, 27.0))
    th = {
        "T_amb": T_amb,
        "Cs": S * rng.uniform(800.0, 1300.0),  # J/K, tread surface layer
        "hc0": S * rng.uniform(5.0, 10.0),  # W/K, surface cooling at standstill
        "hc1": S * rng.uniform(5.0, 9.0),  # W/K per (m/s)^0.8, belt contact + air
        "Gsb": S * rng.uniform(40.0, 70.0),  # W/K, surface <-> bulk
        "Cb": S * rng.uniform(8e3, 14e3),  # J/K, carcass/bulk
        "Gba0": S * rng.uniform(4.0, 8.0),  # W/K, bulk -> ambient
        "Gba1": S * rng.uniform(0.3, 0.7),  # W/K per (m/s)^0.8
        "eta": float(rng.uniform(0.7, 0.95)),  # share of frictional power into the tyre
        "c_rr": float(rng.uniform(0.008, 0.013)),  # rolling-loss coefficient (P = c Fz V)
        "tau_g": float(rng.uniform(60.0, 150.0) if strong_gas else rng.uniform(90.0, 240.0)),
        "r_g": float(rng.uniform(0.75, 0.9) if strong_gas else rng.uniform(0.6, 0.85)),
    }
    th = {k: float(v) for k, v in th.items()}
    if start == "warm":
        Tb0 = T_amb + float(rng.uniform(45.0, 60.0))
        th.update(Ts0=Tb0 - float(rng.uniform(0.0, 5.0)), Tb0=Tb0,
                  Tg0=T_amb + th["r_g"] * (Tb0 - T_amb) * float(rng.uniform(0.6, 0.9)))  # fmt: skip
    else:
        d = float(rng.uniform(0.0, 2.0))
        th.update(Ts0=T_amb + d, Tb0=T_amb + d, Tg0=T_amb + d)
    th["T_set"] = T_amb  # the tyre was inflated at ambient (sealed / unregulated)
    th["start"] = start
    return th


def _noise(rng, tyre: BaseTyre) -> dict:
    k = float(np.sqrt(np.clip(tyre.size, 0.5, 1.5)))
    sF = float(rng.uniform(10.0, 30.0)) * k
    return {
        "Fx_N": sF, "Fy_N": sF * float(rng.uniform(0.9, 1.1)), "Fz_N": 1.5 * sF,
        "Mx_Nm": float(rng.uniform(1.0, 3.0)) * k, "My_Nm": float(rng.uniform(0.5, 1.5)) * k,
        "Mz_Nm": float(rng.uniform(1.0, 3.0)) * k,
        "kappa": float(rng.uniform(1e-4, 3e-4)), "alpha_rad": float(rng.uniform(0.01, 0.03)) * DEG,
        "gamma_rad": 0.01 * DEG, "V_mps": 0.02, "p_Pa": float(rng.uniform(200.0, 500.0)),
        "T_degC": float(rng.uniform(0.3, 0.8)), "T_lag_s": float(rng.uniform(0.7, 1.5)),
        "p_lag_s": 0.2, "aa_cutoff_hz": float(rng.uniform(30.0, 40.0)),
    }  # fmt: skip


def _effect_params(rng, name: str, tyre: BaseTyre, T: float, side: str) -> dict:
    R = tyre.R0 / 0.3135
    if name == "temperature":
        depth = float(rng.uniform(0.25, 0.4))
        slope = float(rng.uniform(0.005, 0.009))  # max slope on the steep side [1/K]
        W_steep = depth * 0.607 / slope
        W_shallow = W_steep * float(rng.uniform(1.5, 2.5))
        # which side is steeper: random, leaning to the side the case runs on
        p_above = {"below": 0.3, "above": 0.7}.get(side, 0.5)
        steep_above = bool(rng.random() < p_above)
        return {"w_surface": float(rng.uniform(0.55, 0.8)), "depth": depth,
                "W_lo": W_shallow if steep_above else W_steep,
                "W_hi": W_steep if steep_above else W_shallow,
                "k_stiff_per_K": float(rng.uniform(0.002, 0.005)), "T_opt": 80.0}  # fmt: skip
    if name == "relaxation":
        return {"sigma_alpha_m": float(rng.uniform(0.4, 0.6)) * R,
                "sigma_kappa_m": float(rng.uniform(0.2, 0.3)) * R,
                "Fc_N": float(rng.uniform(0.35, 0.55)) * tyre.Fz0,
                "alpha_sat_rad": float(rng.uniform(4.0, 8.0)) * DEG,
                "kappa_sat": float(rng.uniform(0.05, 0.1))}  # fmt: skip
    if name == "offset":
        sgn = rng.choice([-1.0, 1.0], size=3)
        return {"ply_steer_rad": float(sgn[0] * rng.uniform(0.05, 0.15)) * DEG,
                "conicity_per_Fz": float(sgn[1] * rng.uniform(0.005, 0.02)),
                "zero_Fx_N": float(sgn[2] * rng.uniform(0.004, 0.012)) * tyre.Fz0}  # fmt: skip
    if name == "speed":
        return {"r0": float(rng.uniform(0.5, 0.75)), "vm_mps": float(rng.uniform(0.05, 0.4)),
                "h": float(rng.uniform(0.3, 0.6))}  # fmt: skip
    if name == "drift":
        return {"loss": float(rng.uniform(0.02, 0.05)), "k_wear_per_J": 0.0}
    if name == "time_delay":
        return {"transport_s": float(rng.uniform(0.010, 0.040)),
                "filter_hz": float(rng.uniform(10.0, 30.0)), "order": 2}  # fmt: skip
    if name == "pressure":
        return {}
    if name == "sidewall_contact":
        return {"depth": float(rng.uniform(0.08, 0.2)),
                "alpha_on0_rad": float(rng.uniform(9.0, 11.0)) * DEG,
                "alpha_w_rad": float(rng.uniform(2.0, 4.0)) * DEG}  # fmt: skip
    return {}


# ------------------------------------------------------------------------------ the plan
def build(case: str, seed: int, minutes: float = 8.0) -> Plan:
    if case not in CASES:
        raise KeyError(f"unknown case {case!r}; --list shows the cases")
    rng = _rng(case, seed)
    T = float(minutes) * 60.0
    tyre = BaseTyre(rng)

    # ---- which physics, and what the bag records
    effects: list[str] = []
    concealed: dict[str, bool] = {}
    imperf: list[str] = []
    side = ""
    pressure_mode = "regulated"
    style = pg.Style()
    rec_T = False
    start = "cold"
    strong_gas = False
    if case in SINGLE:
        effects = [SINGLE[case]]
    elif case in MULTI:
        n = MULTI[case]
        effects = [str(x) for x in rng.choice(MULTI_POOL, size=n, replace=False)]
    else:
        imperf = list(NULLS[case])

    if "temperature" in effects:
        if case == "heat_recorded":
            side = str(rng.choice(["below", "above", "cross"]))
            rec_T = True
        elif case.startswith("heat_"):
            side = case.split("_")[1]
        else:
            side = str(rng.choice(["below", "above", "cross"]))
        concealed["temperature"] = not rec_T
        start = "warm" if side == "above" else "cold"
        style.intense = 1.6 if side in ("above", "cross") else 1.2
        if side in ("above", "cross"):
            style.speeds_kmh = (40.0, 50.0, 60.0, 70.0, 80.0)
        style.pause_prob = 0.45
        style.stop_prob = 0.4
    if "pressure" in effects:
        if case == "pressure_recorded":
            pressure_mode = "setpoints"
            style.n_pressures = (3, 3)
            style.first = "pressure"
            concealed["pressure"] = False
        elif case == "pressure_leak":
            pressure_mode = "leak"
        elif case == "pressure_sealed":
            pressure_mode = "sealed"
            strong_gas = True
            style.intense = 1.6
            style.speeds_kmh = (50.0, 60.0, 70.0, 80.0)
        else:  # multi
            pressure_mode = "sealed" if ("temperature" in effects or rng.random() < 0.5) \
                else "leak"  # fmt: skip
            if pressure_mode == "sealed":
                strong_gas = True
                style.intense = max(style.intense, 1.4)
        if pressure_mode in ("sealed", "leak"):
            concealed["pressure"] = True
            style.pressure_regulated = False
    if "relaxation" in effects or "time_delay" in effects:
        style.rate_range = (1.0, 6.0)
    if "camber" in effects:
        style.camber_values = (0.0, 1.0, 2.0, 3.0, 4.0)
        style.n_cambers = (3, 4)
        style.first = "camber"
    if "combined_slip" in effects:
        style.long_prob = 0.9
        style.long_alpha = (2.0, -2.0, 3.0, -3.0, 4.0, -4.0)
    if "sidewall_contact" in effects:
        style.sidewall = True
        style.p_low = float(rng.uniform(0.4, 0.5))
        style.fz_high = float(rng.uniform(1.35, 1.6))
    if "speed" in effects:
        style.speeds_kmh = (30.0, 70.0, 50.0) if rng.random() < 0.5 else (30.0, 70.0)
        style.n_speeds = (len(style.speeds_kmh), len(style.speeds_kmh))
        style.first = "speed"
    for e in effects:
        concealed.setdefault(e, False)

    rec_p = pressure_mode in ("regulated", "setpoints")
    if imperf:  # nulls: temperature / pressure topics recorded or not
        rec_T = bool(rng.random() < 0.5)
        rec_p = bool(rng.random() < 0.6)
        style.pressure_regulated = rec_p
    elif "temperature" not in effects and pressure_mode not in ("sealed",):
        rec_T = bool(rng.random() < 0.3)
    if not rec_p and pressure_mode == "regulated":
        pressure_mode = "fixed"
    if pressure_mode == "setpoints":
        style.pressure_regulated = True

    prog = pg.build(rng, tyre.Fz0, tyre.p0, T, style)
    tyre.widen_ranges(float(prog.p_set.min()), float(prog.p_set.max()), float(prog.load.max()))

    # ---- true inputs: load servo ripple, belt speed ripple, pressure regulation ripple
    n = prog.t.size
    dt = 0.01
    rot = np.cumsum(prog.V / tyre.R0) * dt + rng.uniform(0, 2 * np.pi)
    a1 = float(rng.uniform(0.002, 0.008))
    Fz = prog.load * (1.0 + a1 * np.sin(rot)) + _ou(rng, n, dt, 0.5, 0.003 * tyre.Fz0)
    V = np.maximum(prog.V + _ou(rng, n, dt, 1.0, 0.01) * (prog.V > 0.5), 0.0)
    p_reg = prog.p_set + (_ou(rng, n, dt, 3.0, 150.0) if style.pressure_regulated else 0.0)
    sliding = ((np.abs(prog.alpha) > 2.0 * DEG) | (np.abs(prog.kappa) > 0.03)) & (prog.V > 1.0)

    th = _thermal(rng, tyre, start, strong_gas)
    eff_params = {e: _effect_params(rng, e, tyre, T, side) for e in effects}
    if "pressure" in eff_params:
        eff_params["pressure"]["mode"] = pressure_mode
        if pressure_mode == "leak":
            f = float(rng.uniform(0.05, 0.2))
            t_l = float(rng.uniform(0.0, 0.25)) * T
            k = (np.sqrt(tyre.p0) - np.sqrt(tyre.p0 * (1 - f))) / max(T - t_l, 1.0)
            eff_params["pressure"].update(fraction=f, t_leak_s=t_l, k_sqrtPa_per_s=float(k))
    nomtemp = round(th["T_amb"], 1)
    models_off = {}
    if "camber" in effects:
        models_off["camber"] = tyre.variant(no_camber=True, nomtemp=nomtemp)
    if "combined_slip" in effects:
        models_off["combined_slip"] = tyre.variant(no_combined=True, nomtemp=nomtemp)
    model_true = tyre.variant(nomtemp=nomtemp)
    model_tir = tyre.variant(no_pressure=(pressure_mode == "setpoints"),
                             no_camber="camber" in effects,
                             no_combined="combined_slip" in effects, nomtemp=nomtemp)  # fmt: skip
    s = ph.Session(prog.t, prog.kappa, prog.alpha, prog.gamma, Fz, V, p_reg, sliding, model_true,
                   models_off, th, eff_params, pressure_mode, tyre.p0, tyre.Fz0, tyre.R0, dt)  # fmt: skip

    # ---- pre-run without effects: frictional power, temperatures, deflections
    base = ph.simulate(s, frozenset())
    s.extras["P_fric_guess"] = base["P_fric"]
    if "temperature" in eff_params:
        _place_optimum(rng, eff_params["temperature"], base, sliding, side, tyre.car)
    if "drift" in eff_params:
        E_tot = float(np.sum(th["eta"] * base["P_fric"]) * dt)
        eff_params["drift"]["k_wear_per_J"] = eff_params["drift"]["loss"] / max(E_tot, 1.0)
        eff_params["drift"]["E_total_J"] = E_tot
    if "sidewall_contact" in eff_params:
        _place_sidewall(eff_params["sidewall_contact"], tyre, prog, Fz)

    plan = Plan(case, seed, minutes, tyre, prog, s, model_tir, effects, concealed, rec_p, rec_T,
                _noise(rng, tyre), imperf, side)  # fmt: skip
    plan.notes["rng_state"] = int(rng.integers(2**31))
    return plan


def _ou(rng, n, dt, tau, sigma):
    """Ornstein-Uhlenbeck noise (time constant tau [s], standard deviation sigma)."""
    from scipy.signal import lfilter

    a = np.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - a * a)
    x = lfilter([1.0], [1.0, -a], w)
    return x


def _place_optimum(rng, e: dict, base: dict, sliding, side: str, car: bool) -> None:
    """Put the grip optimum relative to the session's own tread temperatures."""
    Tg = e["w_surface"] * base["Ts"] + (1 - e["w_surface"]) * base["Tb"]
    x = Tg[sliding] if sliding.any() else Tg
    lo, hi = (60.0, 100.0) if car else (60.0, 110.0)
    if side == "below":
        T_opt = max(float(np.quantile(x, 0.97)) + float(rng.uniform(3.0, 12.0)), lo)
    elif side == "above":
        T_opt = float(np.clip(float(np.quantile(x, 0.05)) - float(rng.uniform(1.0, 6.0)),
                              lo - 5.0, hi))  # fmt: skip
    else:  # cross: somewhere in the middle of the session's range, at least lo if possible
        T_opt = max(float(np.quantile(x, rng.uniform(0.35, 0.6))), lo)
        if np.mean(x > T_opt) < 0.2:
            T_opt = float(np.quantile(x, 0.8))
    e["T_opt"] = round(T_opt, 2)
    e["Tgrip_range_nominal"] = [round(float(np.quantile(x, q)), 1) for q in (0.05, 0.5, 0.95)]


def _place_sidewall(e: dict, tyre: BaseTyre, prog, Fz) -> None:
    """Deflection threshold between the normal conditions and the low-p/high-load corner."""
    P = tyre.P
    Cz0, PFZ1 = float(P["VERTICAL_STIFFNESS"]), float(P["PFZ1"])
    e["Cz0"], e["PFZ1"] = Cz0, PFZ1
    dpi = (prog.p_set - tyre.p0) / tyre.p0
    rho = prog.load / (Cz0 * np.maximum(1 + PFZ1 * dpi, 0.2))
    corner = (prog.p_set < 0.6 * tyre.p0) & (prog.load > 1.25 * tyre.Fz0)
    rho_corner = float(np.max(rho[corner])) if corner.any() else float(np.max(rho))
    rho_norm = float(np.max(rho[~corner]))
    rho_c = rho_norm + 0.45 * (rho_corner - rho_norm)
    e["rho_c_m"] = rho_c
    e["rho_w_m"] = max(0.4 * (rho_corner - rho_c), 1e-4)
    e["rho_corner_m"] = rho_corner
    e["rho_normal_max_m"] = rho_norm
    # the onset slip angle: beyond the peak (95 % of the max force) at the corner
    a = np.radians(np.linspace(0.0, 20.0, 81))
    pl = float(np.min(prog.p_set))
    fh = float(np.max(prog.load))
    o = tyre.model.evaluate(fh, 0.0, a, 0.0, 14.0, pl, full=False)
    F = np.abs(o.Fy)
    a90 = float(a[np.argmax(0.90 * F.max() <= F)])
    e["alpha_90pct_peak_rad"] = a90
    e["alpha_on_min_rad"] = max(a90, 7.0 * DEG)
    e["k_on_rad"] = 4.0 * DEG  # 4 deg earlier per 100 % extra deflection
