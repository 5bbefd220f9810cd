"""Time simulation of the brush tyre on the rig: thermal nodes, gas, relaxation, wear, effects.

``simulate`` runs one session sample by sample (numba); ``post`` applies what happens between
the tyre and the recorded force channels (load-cell zero offsets, DAQ delay and filter).
Every effect has its own switch, so that the same session can be re-run with one effect off
(the "without" runs behind truth.json's ms_N2).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.signal import butter, lfilter, lfilter_zi

from . import tyre as ty

DT = 0.01  # slip sample period [s] (100 Hz)
PATM = 101325.0

# ------------------------------------------------------------------------------------------
# effect / session parameter vector E (indices are numba compile-time constants)
# ------------------------------------------------------------------------------------------
# thermal model (always running: it drives the temperature topic and the gas)
E_CS = 0  # surface layer heat capacity [J/K]
E_CB = 1  # bulk (tread + carcass) heat capacity [J/K]
E_CG = 2  # inflation gas (+ rim share) heat capacity [J/K]
E_HSB = 3  # surface <-> bulk conductance [W/K]
E_HSA = 4  # surface -> ambient convection at VREF [W/K] (~ V^0.8)
E_HBA = 5  # bulk -> ambient at VREF [W/K] (~ V^0.8)
E_HBG = 6  # bulk <-> gas [W/K]
E_HGA = 7  # gas -> rim/ambient [W/K]
E_ETA = 8  # share of the sliding power that heats the surface layer [-]
E_ETAR = 9  # share of the rolling-resistance power that heats the bulk [-]
E_TA = 10  # ambient [degC]
E_T0S = 11  # initial surface temperature [degC]
E_T0B = 12  # initial bulk temperature [degC]
E_T0G = 13  # initial gas temperature [degC]
E_TNOM = 14  # temperature at which model.tir was characterised [degC]
# temperature effect: grip window on the surface temperature, stiffness on the bulk
E_TEMP_ON = 15
E_TOPT = 16  # grip optimum [degC]
E_TCW = 17  # grip loss at TWID from the optimum [-]
E_TWID = 18  # window scale [degC]
E_TKS = 19  # tread stiffness loss per degC of bulk temperature [1/degC]
# pressure: 0 = regulated to the set point, 1 = sealed (gas law, re-set at each set point
# change), 2 = slow leak; PCONST = 1: the tyre sees NOMPRES whatever the gas does
E_PMODE = 20
E_LEAK_F = 21  # fraction of the gauge pressure lost by the end of the session [-]
E_LEAK_TAU = 22  # leak time constant [s]
E_T_END = 23  # session length [s]
E_PCONST = 24
# relaxation: the slips the tyre feels lag over the travelled distance
E_RELAX_ON = 25
E_SIGA0 = 26  # lateral relaxation length at FZ0 with the patch adhering [m]
E_SIGK0 = 27  # longitudinal relaxation length at FZ0 [m]
E_NSIG = 28  # load exponent [-]
E_SMIN = 29  # share left when the whole patch slides [-]
# wear
E_WEAR_ON = 30
E_WEAR_RATE = 31  # grip loss per J of sliding energy [1/J]
E_WEAR_STIFF = 32  # tread stiffening per unit grip loss [-]
# speed: sliding friction follows the actual sliding speed, V_eff = VREF (V/VREF)^LAM
E_SPEED_ON = 33
E_SPEED_LAM = 34
# camber physics, combined-slip interaction (1 = present)
E_CAMBER_ON = 35
E_COMB_ON = 36
# offsets inside the tyre: ply-steer residual slip angle, conicity residual camber [rad]
E_OFF_ON = 37
E_PLY_ALPHA = 38
E_CON_GAMMA = 39
# sidewall contact: Fy (and Mz, Mx) drop by SW_D, gated by deflection above SW_DC (ramp
# SW_WD [m]), beyond |alpha| = SW_A0 * SW_DC/deflection (ramp SW_WA [rad])
E_SW_ON = 40
E_SW_D = 41
E_SW_DC = 42
E_SW_WD = 43
E_SW_A0 = 44
E_SW_WA = 45
N_E = 46

OUT_NAMES = ("Fx", "Fy", "Mz", "Mx", "My", "Ts", "Tb", "Tg", "p", "wear", "Psl", "alpha_eff",
             "kappa_eff")  # fmt: skip
N_SIM_OUT = len(OUT_NAMES)


def evec(**kw) -> np.ndarray:
    """An E vector: camber and combined-slip physics on, everything else off, plus ``kw``."""
    E = np.zeros(N_E)
    E[E_CAMBER_ON] = 1.0
    E[E_COMB_ON] = 1.0
    E[E_SPEED_LAM] = 1.0
    E[E_TWID] = 50.0
    E[E_SMIN] = 0.3
    E[E_LEAK_TAU] = 1e9
    E[E_T_END] = 1.0
    E[E_SW_WD] = 1.0
    E[E_SW_WA] = 1.0
    for k, v in kw.items():
        E[globals()["E_" + k]] = v
    return E


@njit(cache=True, inline="always")
def _smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True)
def _window(E, T):
    """Grip window 1 - TCW ((T - TOPT)/TWID)^2, not below 0.4."""
    d = (T - E[E_TOPT]) / E[E_TWID]
    return max(1.0 - E[E_TCW] * d * d, 0.4)


@njit(cache=True)
def _simulate(T, E, t, Fz, kappa, alpha, gamma, V, pset, reset):
    n = t.shape[0]
    out = np.empty((N_SIM_OUT, n))
    o = np.empty(ty.N_OUT)
    o2 = np.empty(ty.N_OUT)
    Ts = E[E_T0S]
    Tb = E[E_T0B]
    Tg = E[E_T0G]
    Tnom = E[E_TNOM]
    Wnom = _window(E, Tnom)
    p_ref_abs = pset[0] + PATM
    Tg_ref = Tg
    a_l = alpha[0]
    k_l = kappa[0]
    adh = 1.0
    wear = 0.0
    Fz0 = T[ty.FZ0]
    P0 = T[ty.P0]
    R0 = T[ty.R0]
    VREF = T[ty.VREF]
    t0 = t[0]
    pmode = int(E[E_PMODE])
    speed_on = E[E_SPEED_ON] > 0.5
    for i in range(n):
        v = V[i]
        fz = Fz[i]
        # ---- inflation pressure
        if pmode == 1:
            if reset[i]:
                p_ref_abs = pset[i] + PATM
                Tg_ref = Tg
            p = p_ref_abs * (Tg + 273.15) / (Tg_ref + 273.15) - PATM
        elif pmode == 2:
            tau = E[E_LEAK_TAU]
            frac = (1.0 - math.exp(-(t[i] - t0) / tau)) / (1.0 - math.exp(-E[E_T_END] / tau))
            p = pset[i] * (1.0 - E[E_LEAK_F] * frac)
        else:
            p = pset[i]
        p_used = P0 if E[E_PCONST] > 0.5 else p
        # ---- grip and stiffness factors
        mu_s = 1.0
        c_s = 1.0
        if E[E_TEMP_ON] > 0.5:
            mu_s = _window(E, Ts) / Wnom
            c_s = max(1.0 - E[E_TKS] * (Tb - Tnom), 0.5)
        if E[E_WEAR_ON] > 0.5:
            mu_s *= 1.0 - wear
            c_s *= 1.0 + E[E_WEAR_STIFF] * wear
        # ---- slips as the tyre feels them (relaxation over the travelled distance)
        if E[E_RELAX_ON] > 0.5:
            load = max(fz, 0.05 * Fz0) / Fz0
            shape = (E[E_SMIN] + (1.0 - E[E_SMIN]) * adh) * load ** E[E_NSIG]
            ds = max(abs(v), 0.1) * DT
            a_l += (alpha[i] - a_l) * (1.0 - math.exp(-ds / (E[E_SIGA0] * shape)))
            k_l += (kappa[i] - k_l) * (1.0 - math.exp(-ds / (E[E_SIGK0] * shape)))
            al = a_l
            kl = k_l
        else:
            al = alpha[i]
            kl = kappa[i]
        gam = gamma[i] if E[E_CAMBER_ON] > 0.5 else 0.0
        if E[E_OFF_ON] > 0.5:
            al += E[E_PLY_ALPHA]
            gam += E[E_CON_GAMMA]
        # speed law: sliding friction at V_eff (the brush uses VREF when speed_on is False)
        Vb = v
        if speed_on:
            Vb = VREF * (max(abs(v), 0.1) / VREF) ** E[E_SPEED_LAM]
        # ---- brush
        if E[E_COMB_ON] > 0.5:
            ty.brush_point(T, fz, kl, al, gam, Vb, p_used, mu_s, c_s, speed_on, o)
            Fx = o[0]
            Fy = o[1]
            Mz = o[2]
            Mx = o[3]
            Psl = o[5]
            adh = o[6]
        else:  # no interaction: each force from its own pure-slip brush
            ty.brush_point(T, fz, kl, 0.0, gam, Vb, p_used, mu_s, c_s, speed_on, o)
            ty.brush_point(T, fz, 0.0, al, gam, Vb, p_used, mu_s, c_s, speed_on, o2)
            Fx = o[0]
            Fy = o2[1]
            Mz = o2[2]
            Mx = o2[3]
            Psl = o[5] + o2[5]
            adh = min(o[6], o2[6])
        # rolling resistance at the true speed (brush_point's My uses its V argument)
        vr = v / VREF
        My = -R0 * Fz0 * (T[ty.QSY1] + T[ty.QSY3] * abs(vr) + T[ty.QSY4] * vr**4) * (
            (max(fz, 0.0) / Fz0) ** T[ty.QSY7]) * ((p_used / P0) ** T[ty.QSY8])  # fmt: skip
        if speed_on:  # the heat follows the true sliding speed V |s|, not V_eff |s|
            Psl = Psl * abs(v) / max(Vb, 0.1)
        # ---- sidewall contact: deflection-gated extra drop beyond the peak
        if E[E_SW_ON] > 0.5:
            d = ty.deflection(T, fz, p_used)
            gate = _smoothstep((d - E[E_SW_DC]) / E[E_SW_WD])
            a_on = E[E_SW_A0] * E[E_SW_DC] / max(d, 1e-6)
            hs = _smoothstep((abs(al) - a_on) / E[E_SW_WA])
            f = 1.0 - E[E_SW_D] * gate * hs
            Fy *= f
            Mz *= f
            Mx *= f
        # ---- thermal nodes (explicit Euler; dt << the time constants)
        conv = (max(abs(v), 0.5) / VREF) ** 0.8
        Proll = abs(My) * abs(v) / R0
        qs = E[E_ETA] * Psl - E[E_HSB] * (Ts - Tb) - E[E_HSA] * conv * (Ts - E[E_TA])
        qb = (E[E_HSB] * (Ts - Tb) + E[E_ETAR] * Proll - E[E_HBA] * conv * (Tb - E[E_TA])
              - E[E_HBG] * (Tb - Tg))  # fmt: skip
        qg = E[E_HBG] * (Tb - Tg) - E[E_HGA] * (Tg - E[E_TA])
        Ts += DT * qs / E[E_CS]
        Tb += DT * qb / E[E_CB]
        Tg += DT * qg / E[E_CG]
        # ---- wear: irreversible grip loss with the sliding energy
        if E[E_WEAR_ON] > 0.5:
            wear += E[E_WEAR_RATE] * Psl * DT
        out[0, i] = Fx
        out[1, i] = Fy
        out[2, i] = Mz
        out[3, i] = Mx
        out[4, i] = My
        out[5, i] = Ts
        out[6, i] = Tb
        out[7, i] = Tg
        out[8, i] = p
        out[9, i] = wear
        out[10, i] = Psl
        out[11, i] = al
        out[12, i] = kl
    return out


def simulate(T, E, prog) -> dict:
    """Run the session ``prog`` (a Programme) with tyre T and effects E; dict of arrays."""
    res = _simulate(np.asarray(T, float), np.asarray(E, float), prog.t, prog.Fz, prog.kappa,
                    prog.alpha, prog.gamma, prog.V, prog.pset, prog.reset)  # fmt: skip
    return {k: res[i] for i, k in enumerate(OUT_NAMES)}


# ------------------------------------------------------------------------------------------
# between the tyre and the recorded channels
# ------------------------------------------------------------------------------------------
def delay_filter(x: np.ndarray, tau: float, fc: float, order: int = 2) -> np.ndarray:
    """Transport delay ``tau`` [s] (linear interpolation) then a Butterworth low pass
    (cut-off ``fc`` [Hz], started in steady state) on a 100 Hz channel."""
    n = len(x)
    s = np.arange(n) - tau / DT
    y = np.interp(s, np.arange(n), x)  # before the start: the first value
    if fc > 0:
        b, a = butter(order, fc / (0.5 / DT))
        y, _ = lfilter(b, a, y, zi=lfilter_zi(b, a) * y[0])
    return y


def post(sim: dict, Fz: np.ndarray, delay: dict | None, zeros: dict | None) -> dict:
    """True measured channels (N, 6): Fx Fy Fz Mx My Mz at the hub load cell.

    ``zeros``: constant load-cell zero offsets (the offset effect) {"Fx", "Fy", "Mz"};
    ``delay``: {"tau": s, "fc": Hz} DAQ transport delay and filter (the time_delay effect).
    """
    ch = np.stack([sim["Fx"], sim["Fy"], Fz, sim["Mx"], sim["My"], sim["Mz"]], axis=1).copy()
    if zeros:
        ch[:, 0] += zeros.get("Fx", 0.0)
        ch[:, 1] += zeros.get("Fy", 0.0)
        ch[:, 5] += zeros.get("Mz", 0.0)
    if delay:
        for k in range(6):
            ch[:, k] = delay_filter(ch[:, k], delay["tau"], delay["fc"])
    return ch
