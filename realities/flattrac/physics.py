"""The physics of the flattrac rig: everything the generator adds to the .tir's force law.

All forms are this generator's own (see README.md for the equations and ranges):

- base force law: ``TireModel.evaluate`` of the tyre (steady state at the given Fz, slips,
  inclination, belt speed and inflation pressure);
- friction/stiffness scaling by the similarity method: with a friction factor ``s_mu`` and a
  stiffness factor ``s_K``, ``F = s_mu * F0(kappa * s_K/s_mu, alpha * s_K/s_mu)`` (peak scales
  with s_mu, slope at zero slip with s_K);
- three-node thermal model (tread surface, carcass/bulk, inflation gas) heated by frictional
  power and rolling loss, cooled by the belt and ambient;
- grip window of the tread temperature (skewed Gaussian-like), carcass stiffness law;
- gas law for a sealed tyre, orifice law for a slow leak;
- first-order relaxation in travelled distance with load- and slip-dependent lengths;
- Savkoor-type friction against sliding speed; energy-driven wear; deflection-gated sidewall
  contact; ply-steer, conicity and load-cell zero; DAQ transport delay and filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import signal

P_ATM = 101325.0
K0 = 273.15


# ----------------------------------------------------------------------------- numba loops
@njit(cache=True)
def thermal_nodes(dt, P_fric, P_roll, V, T_amb, Ts0, Tb0, Tg0, Cs, Cb, hc0, hc1, Gsb, Gba0,
                  Gba1, eta, tau_g, r_g):  # fmt: skip
    """Tread surface Ts, bulk/carcass Tb and gas Tg [degC] (semi-implicit Euler, step dt)."""
    n = P_fric.shape[0]
    Ts = np.empty(n)
    Tb = np.empty(n)
    Tg = np.empty(n)
    ts, tb, tg = Ts0, Tb0, Tg0
    for k in range(n):
        Ts[k] = ts
        Tb[k] = tb
        Tg[k] = tg
        v08 = max(V[k], 0.0) ** 0.8
        hc = hc0 + hc1 * v08
        gba = Gba0 + Gba1 * v08
        # surface: friction heat in, belt/air cooling, conduction to the bulk
        a = dt / Cs
        ts = (ts + a * (eta * P_fric[k] + hc * T_amb + Gsb * tb)) / (1.0 + a * (hc + Gsb))
        # bulk: conduction from the surface, rolling loss, cooling to ambient (sidewall, rim)
        b = dt / Cb
        tb = (tb + b * (Gsb * ts + P_roll[k] + gba * T_amb)) / (1.0 + b * (Gsb + gba))
        # gas: follows the inner liner (bulk) and the rim (ambient) with its own lag
        tg = tg + dt / tau_g * (r_g * tb + (1.0 - r_g) * T_amb - tg)
    return Ts, Tb, Tg


@njit(cache=True)
def relax(dt, x, V, Fz, sig_nom, Fz0, Fc, x_sat, sig_min_frac):
    """First-order lag in travelled distance: sigma dx'/ds + x' = x (first-order hold).

    sigma = sig_nom * L(Fz) / (1 + (|x'|/x_sat)^2), L(Fz) = (1-exp(-Fz/Fc))/(1-exp(-Fz0/Fc)),
    never below sig_min_frac * sig_nom * L(Fz). The state holds while the belt stands still.
    """
    n = x.shape[0]
    y = np.empty(n)
    y[0] = x[0]
    norm = 1.0 - np.exp(-Fz0 / Fc)
    for k in range(1, n):
        ds = 0.5 * (max(V[k - 1], 0.0) + max(V[k], 0.0)) * dt
        if ds <= 1e-9:
            y[k] = y[k - 1]
            continue
        L = (1.0 - np.exp(-max(Fz[k - 1], 0.0) / Fc)) / norm
        r = abs(y[k - 1]) / x_sat
        sig = sig_nom * L / (1.0 + r * r)
        sig = max(sig, sig_min_frac * sig_nom * L, 1e-3)
        e = np.exp(-ds / sig)
        y[k] = x[k] - (x[k] - x[k - 1]) * (sig / ds) * (1.0 - e) + (y[k - 1] - x[k - 1]) * e
    return y


# ----------------------------------------------------------------------------- laws
def grip_window(T, T_opt, W_lo, W_hi, depth):
    """Skewed window: 1 at T_opt, falling to 1 - depth far away, width W_lo below, W_hi above."""
    W = np.where(T_opt > T, W_lo, W_hi)
    x = (T - T_opt) / W
    return 1.0 - depth * (1.0 - np.exp(-0.5 * x * x))


def savkoor(Vs, r0, vm, h):
    """Friction against sliding speed: r0 + (1-r0) exp(-h^2 log10^2(Vs/vm)) (peak 1 at vm)."""
    lg = np.log10(np.maximum(Vs, 0.05) / vm)  # below 5 cm/s: the adhesion region, no sliding
    return r0 + (1.0 - r0) * np.exp(-(h * h) * lg * lg)


def sealed_pressure(Tg, p_set, T_set):
    """Gauge pressure of a sealed tyre set to p_set (gauge) at gas temperature T_set [degC]."""
    return (p_set + P_ATM) * (Tg + K0) / (T_set + K0) - P_ATM


def leak_pressure(t, p0, t_leak, k):
    """Orifice leak dp/dt = -2 k sqrt(p): p = (sqrt(p0) - k (t - t_leak)+)^2."""
    return (np.sqrt(p0) - k * np.maximum(t - t_leak, 0.0)) ** 2


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


# ----------------------------------------------------------------------------- the session
@dataclass
class Session:
    """True inputs of one session and all physical parameters (built in :mod:`.cases`)."""

    t: np.ndarray
    kappa: np.ndarray
    alpha: np.ndarray
    gamma: np.ndarray
    Fz: np.ndarray  # true load (set point plus servo ripple)
    V: np.ndarray
    p_reg: np.ndarray  # the pressure the rig holds when regulated (p0 when not)
    sliding: np.ndarray  # bool: samples with real slip (for normalisations)
    model_true: object  # TireModel of the real tyre
    models_off: dict  # effect name -> TireModel without that physics (camber, combined)
    thermal: dict
    effects: dict  # name -> parameter dict (only the session's effects)
    pressure_mode: str  # "regulated", "fixed", "sealed", "leak", "setpoints"
    p0: float
    Fz0: float
    R0: float
    dt: float = 0.01
    extras: dict = field(default_factory=dict)


def _pressure(s: Session, Tg: np.ndarray, on: frozenset) -> np.ndarray:
    """The pressure the tyre has (true) and the one it 'sees' with the pressure effect off."""
    mode = s.pressure_mode
    if mode == "sealed":
        p = sealed_pressure(Tg, s.p0, s.thermal["T_set"])
    elif mode == "leak":
        e = s.effects["pressure"]
        p = leak_pressure(s.t, s.p0, e["t_leak_s"], e["k_sqrtPa_per_s"])
    else:  # regulated, fixed, setpoints: what the regulator holds
        p = s.p_reg
    return p


def simulate(s: Session, on: frozenset, n_iter: int | None = None) -> dict:
    """Simulate the session with the effects in ``on`` switched on; returns true channels."""
    E = s.effects
    th = s.thermal
    V = s.V
    Fz = s.Fz
    kap = s.kappa.copy()
    alp = s.alpha.copy()
    if "offset" in on:
        alp = alp + E["offset"]["ply_steer_rad"]
    if "relaxation" in on:
        r = E["relaxation"]
        alp = relax(s.dt, alp, V, Fz, r["sigma_alpha_m"], s.Fz0, r["Fc_N"], r["alpha_sat_rad"],
                    0.25)  # fmt: skip
        kap = relax(s.dt, kap, V, Fz, r["sigma_kappa_m"], s.Fz0, r["Fc_N"], r["kappa_sat"], 0.25)
    tan_a = np.tan(alp)
    Vs = V * np.sqrt(kap * kap + tan_a * tan_a)
    s_speed = 1.0
    if "speed" in on:
        e = E["speed"]
        m = savkoor(Vs, e["r0"], e["vm_mps"], e["h"])
        s_speed = m / np.median(m[s.sliding])
    model = s.model_true
    if "camber" not in on and "camber" in s.models_off:
        model = s.models_off["camber"]
    if "combined_slip" not in on and "combined_slip" in s.models_off:
        model = s.models_off["combined_slip"]
    coupled = ("temperature" in on or "drift" in on
               or ("pressure" in on and s.pressure_mode == "sealed"))  # fmt: skip
    if n_iter is None:
        n_iter = 2 if coupled else 1
    P_roll = th["c_rr"] * Fz * np.maximum(V, 0.0)
    P_fric = s.extras.get("P_fric_guess")
    if P_fric is None:
        P_fric = np.zeros_like(V)
    gamma = s.gamma
    for it in range(n_iter + 1):
        Ts, Tb, Tg = thermal_nodes(s.dt, P_fric, P_roll, V, th["T_amb"], th["Ts0"], th["Tb0"],
                                   th["Tg0"], th["Cs"], th["Cb"], th["hc0"], th["hc1"], th["Gsb"],
                                   th["Gba0"], th["Gba1"], th["eta"], th["tau_g"], th["r_g"])  # fmt: skip
        p_true = _pressure(s, Tg, on)
        p_eval = p_true if ("pressure" in on or "pressure" not in E) else np.full_like(V, s.p0)
        s_mu = np.ones_like(V) * s_speed
        s_K = np.ones_like(V)
        if "temperature" in on:
            e = E["temperature"]
            Tgrip = e["w_surface"] * Ts + (1.0 - e["w_surface"]) * Tb
            win = grip_window(Tgrip, e["T_opt"], e["W_lo"], e["W_hi"], e["depth"])
            s_mu = s_mu * win / np.median(win[s.sliding])
            stiff = np.exp(-e["k_stiff_per_K"] * (Tb - np.median(Tb[s.sliding])))
            s_K = s_K * stiff
        if "drift" in on:
            Ef = np.cumsum(th["eta"] * P_fric) * s.dt
            s_mu = s_mu * (1.0 - E["drift"]["k_wear_per_J"] * Ef)
        q = s_K / s_mu
        o = model.evaluate(Fz, kap * q, alp * q, gamma, V, p_eval, full=False)
        Fx = s_mu * o.Fx
        Fy = s_mu * o.Fy
        Mz = s_mu * o.Mz
        Mx = np.array(o.Mx)
        My = np.array(o.My)
        if "sidewall_contact" in on:
            e = E["sidewall_contact"]
            dpi = (p_true - s.p0) / s.p0
            Cz = e["Cz0"] * np.maximum(1.0 + e["PFZ1"] * dpi, 0.2)
            rho = Fz / Cz
            g = smoothstep((rho - e["rho_c_m"]) / e["rho_w_m"])
            a_on = np.maximum(e["alpha_on0_rad"] - e["k_on_rad"] * (rho / e["rho_c_m"] - 1.0),
                              e["alpha_on_min_rad"])  # fmt: skip
            over = np.maximum(np.abs(alp) - a_on, 0.0)
            drop = g * e["depth"] * (1.0 - np.exp(-over / e["alpha_w_rad"]))
            Fy = Fy * (1.0 - drop)
            Mz = Mz * (1.0 - drop)
        P_fric = np.abs(Fx * V * kap) + np.abs(Fy * V * tan_a)
        if not coupled:
            # the temperatures are a passive output here: integrate them from these forces
            Ts, Tb, Tg = thermal_nodes(s.dt, P_fric, P_roll, V, th["T_amb"], th["Ts0"],
                                       th["Tb0"], th["Tg0"], th["Cs"], th["Cb"], th["hc0"],
                                       th["hc1"], th["Gsb"], th["Gba0"], th["Gba1"], th["eta"],
                                       th["tau_g"], th["r_g"])  # fmt: skip
            p_true = _pressure(s, Tg, on)
            break
    out = {"Fx": Fx, "Fy": Fy, "Fz": Fz.copy(), "Mx": Mx, "My": My, "Mz": Mz, "Fz_load": Fz,
           "Ts": Ts, "Tb": Tb, "Tg": Tg, "p": p_true, "s_mu": s_mu, "s_K": s_K,
           "P_fric": P_fric, "kappa_eff": kap, "alpha_eff": alp}  # fmt: skip
    if "offset" in on:
        e = E["offset"]
        out["Fy"] = out["Fy"] + e["conicity_per_Fz"] * Fz
        out["Fx"] = out["Fx"] + e["zero_Fx_N"]
    if "time_delay" in on:
        e = E["time_delay"]
        for ch in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"):
            out[ch] = daq_delay(s.t, out[ch], e["transport_s"], e["filter_hz"], e["order"], s.dt)
    return out


def daq_delay(t, x, tau, fc, order, dt):
    """Transport delay tau (linear interpolation) then a causal Butterworth low-pass."""
    y = np.interp(t - tau, t, x, left=x[0])
    if fc and fc > 0:
        b, a = signal.butter(order, fc, fs=1.0 / dt)
        zi = signal.lfilter_zi(b, a) * y[0]
        y, _ = signal.lfilter(b, a, y, zi=zi)
    return y


def butter_group_delay(fc, order, fs):
    """Low-frequency group delay of the Butterworth filter [s]."""
    b, a = signal.butter(order, fc, fs=fs)
    w, gd = signal.group_delay((b, a), w=[0.5], fs=fs)
    return float(gd[0]) / fs
