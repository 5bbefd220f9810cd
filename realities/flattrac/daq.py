"""The rig's data acquisition: sensor noise, anti-alias filtering, sensor lags, quantisation
and the real-world imperfections of the null cases (gain error, spikes, dropouts, wandering
zero). The noise-free twin is made from the same true channels without any of this.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

FORCE_CH = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def coloured_noise(rng, n, sigma, fir):
    """White noise through the DAQ's linear-phase anti-alias FIR, rescaled to ``sigma``."""
    w = rng.standard_normal(n + len(fir))
    x = np.convolve(w, fir, mode="same")[:n]
    return x * (sigma / np.sqrt(np.sum(fir * fir)))


def first_order_lag(t, x, tau):
    """A sensor's first-order lag on the uniform grid ``t`` (starts settled at x[0])."""
    if tau <= 0 or t.size < 2:
        return x.copy()
    ak = np.exp(-(t[1] - t[0]) / tau)
    y, _ = signal.lfilter([1 - ak], [1.0, -ak], x, zi=[ak * x[0]])
    return y


def quantise(x, q):
    return np.round(x / q) * q


def draw_imperfections(rng, kinds, n, dt, noise, mild=False):
    """Parameters of the imperfections (what truth.json lists)."""
    out = []
    for kind in kinds:
        if kind == "gain":
            g = rng.uniform(0.005, 0.03) * rng.choice([-1.0, 1.0], size=2)
            out.append({"kind": "gain", "Fx_gain": float(1 + g[0]),
                        "Fy_gain": float(1 + g[1] * rng.uniform(0.3, 1.0)),
                        "Fz_gain": float(1 + g[0] * rng.uniform(0.0, 0.5)),
                        "note": "load-cell calibration gain error on measured_forces"})  # fmt: skip
        elif kind == "spikes":
            rate = 1.0 / 5000.0 * rng.uniform(0.7, 1.3)
            k = max(int(rng.poisson(rate * n)), 2)
            idx = np.sort(rng.choice(np.arange(10, n - 10), size=k, replace=False))
            ch = rng.choice(["Fx", "Fy", "Fz"], size=k, p=[0.4, 0.4, 0.2])
            amp = rng.uniform(5.0, 30.0, size=k) * rng.choice([-1.0, 1.0], size=k)
            width = rng.integers(1, 3, size=k)
            out.append({"kind": "spikes", "count": int(k), "per_samples": round(n / k, 1),
                        "sigmas": [5.0, 30.0],
                        "list": [{"i": int(i), "channel": str(c), "sigmas": round(float(a), 2),
                                  "samples": int(w)} for i, c, a, w in zip(idx, ch, amp, width,
                                                                           strict=True)]})  # fmt: skip
        elif kind == "dropouts":
            k = int(rng.integers(2, 5)) if mild else int(rng.integers(4, 10))
            gaps = []
            for _ in range(k):
                dur = float(rng.uniform(0.05, 0.5))
                i0 = int(rng.integers(100, n - 100))
                topics = rng.choice(["slip", "load", "measured_forces", "velocity", "pressure",
                                     "temperature"], size=int(rng.integers(1, 3)), replace=False)  # fmt: skip
                gaps.append({"t0_s": round(i0 * dt, 2), "duration_s": round(dur, 3),
                             "topics": sorted(str(x) for x in topics)})  # fmt: skip
            out.append({"kind": "dropouts", "gaps": gaps})
        elif kind == "zero_walk":
            out.append({"kind": "zero_walk", "Fx_rms_N": float(rng.uniform(2.0, 5.0)),
                        "Fy_rms_N": float(rng.uniform(2.0, 5.0)),
                        "tau_s": float(rng.uniform(60.0, 180.0)),
                        "note": "load-cell zero wandering as a slow random walk within spec"})  # fmt: skip
    return out


def _ou(rng, n, dt, tau, sigma):
    a = np.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - a * a)
    x0 = rng.standard_normal() * sigma
    x, _ = signal.lfilter([1.0], [1.0, -a], w, zi=[a * x0])
    return x


def make_channels(rng, t_abs, true: dict, noise: dict, imperf: list, rec_p: bool, rec_T: bool,
                  dt: float = 0.01):  # fmt: skip
    """(recording, twin) as {channel: (t, values)} for ``realities._bag.write_bag``."""
    n = t_abs.size
    fir = signal.firwin(31, noise["aa_cutoff_hz"], fs=1.0 / dt)
    slip_true = np.column_stack([true["kappa"], true["alpha"], true["gamma"]])
    F_true = np.column_stack([true[c] for c in FORCE_CH])

    # ---- recording: noise (coloured by the AA filter), lags, quantisation
    slip = slip_true + np.column_stack([
        coloured_noise(rng, n, noise["kappa"], fir),
        coloured_noise(rng, n, noise["alpha_rad"], fir),
        coloured_noise(rng, n, noise["gamma_rad"], fir)])  # fmt: skip
    load = true["Fz_load"] + coloured_noise(rng, n, noise["Fz_N"], fir)  # the rig's load channel
    sig = {"Fx": noise["Fx_N"], "Fy": noise["Fy_N"], "Fz": noise["Fz_N"], "Mx": noise["Mx_Nm"],
           "My": noise["My_Nm"], "Mz": noise["Mz_Nm"]}  # fmt: skip
    F = F_true.copy()
    for imp in imperf:
        if imp["kind"] == "gain":
            F[:, 0] *= imp["Fx_gain"]
            F[:, 1] *= imp["Fy_gain"]
            F[:, 2] *= imp["Fz_gain"]
        elif imp["kind"] == "zero_walk":
            F[:, 0] += _ou(rng, n, dt, imp["tau_s"], imp["Fx_rms_N"])
            F[:, 1] += _ou(rng, n, dt, imp["tau_s"], imp["Fy_rms_N"])
    for j, c in enumerate(FORCE_CH):
        F[:, j] += coloured_noise(rng, n, sig[c], fir)
    for imp in imperf:
        if imp["kind"] == "spikes":
            for sp in imp["list"]:
                j = FORCE_CH.index(sp["channel"])
                F[sp["i"] : sp["i"] + sp["samples"], j] += sp["sigmas"] * sig[sp["channel"]]
    V = true["V"] + rng.standard_normal(n) * noise["V_mps"] * (true["V"] > 0.05)
    t_rel = t_abs - t_abs[0]
    p_meas = quantise(first_order_lag(t_rel, true["p"], noise["p_lag_s"])
                      + rng.standard_normal(n) * noise["p_Pa"], 100.0)  # fmt: skip
    T_meas = quantise(first_order_lag(t_rel, true["Ts"], noise["T_lag_s"])
                      + rng.standard_normal(n) * noise["T_degC"], 0.1)  # fmt: skip

    keep = {k: np.ones(n, bool) for k in ("slip", "load", "measured_forces", "velocity",
                                          "pressure", "temperature")}  # fmt: skip
    for imp in imperf:
        if imp["kind"] == "dropouts":
            for g in imp["gaps"]:
                m = (t_rel >= g["t0_s"]) & (t_rel < g["t0_s"] + g["duration_s"])
                for topic in g["topics"]:
                    keep[topic] &= ~m
    ks = keep["slip"]
    slow = np.zeros(n, bool)
    slow[::10] = True  # pressure and temperature sensors at 10 Hz, velocity at 20 Hz
    vel = np.zeros(n, bool)
    vel[::5] = True
    rec = {
        "slip": (t_abs[ks], slip[ks]),
        "load": (t_abs[keep["load"]], load[keep["load"]]),
        "measured_forces": (t_abs[keep["measured_forces"]], F[keep["measured_forces"]]),
        "velocity": (t_abs[keep["velocity"] & vel], V[keep["velocity"] & vel]),
    }
    if rec_p:
        m = keep["pressure"] & slow
        rec["pressure"] = (t_abs[m], p_meas[m])
    if rec_T:
        m = keep["temperature"] & slow
        rec["temperature"] = (t_abs[m], T_meas[m])
    # ---- twin: true values of every channel, stamped at the recording's slip stamps: slip,
    # load and forces at every one, the slow channels (speed, pressure, tread temperature) at
    # every 5th (20 Hz; keeps the bag writing within the time budget)
    k5 = ks & vel
    twin = {
        "slip": (t_abs[ks], slip_true[ks]),
        "load": (t_abs[ks], true["Fz_load"][ks]),
        "measured_forces": (t_abs[ks], F_true[ks]),
        "velocity": (t_abs[k5], true["V"][k5]),
        "pressure": (t_abs[k5], true["p"][k5]),
        "temperature": (t_abs[k5], true["Ts"][k5]),
    }
    return rec, twin
